"""vpr_core: landmark-based visual place recognition workbench, reproducing Yang et al., "Towards
A Deep Insight into Landmark-based Visual Place Recognition: Methodology and Practice": landmarks,
CNN descriptors, Eq. (1)-(2) matching, scale statistics, selection and overlap schemes."""

from __future__ import annotations

__version__ = "0.1.0"

from .utils import make_deterministic

__all__ = ["__version__", "make_deterministic"]
