"""vpr_core: landmark-based visual place recognition workbench.

Reproduces Yang et al., "Towards A Deep Insight into Landmark-based Visual Place Recognition:
Methodology and Practice": Edge Box / dense landmarks, CNN landmark descriptors, reciprocal
matching scored by Eq. (1)-(2), scale statistics (CMR/CLS/ASL), selection and overlap schemes.
"""

from __future__ import annotations

__version__ = "0.1.0"

from .utils import make_deterministic  # noqa: F401
