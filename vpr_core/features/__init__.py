"""Landmark descriptors: crops or RoI pooling -> CNN (or handcrafted) features -> projection.

``LandmarkEncoder(backbone, dim, seed, device, pooling)`` turns an image and its landmark boxes
into one descriptor per box (Sec. 2.1). One concept per file:

* :mod:`.encoder`: :class:`LandmarkEncoder` (the two pooling modes, projection, ``encode_global``),
* :mod:`.crops`: ``crop`` mode's box crops (kornia ``crop_and_resize``, anti-alias pyramid),
* :mod:`.roi`: ``roi`` mode's working-size image and bilinear RoIAlign,
* :mod:`.projection`: the Gaussian random projection.

Backbones are looked up by name in :mod:`vpr_core.backbones` (``available_backbones()``).
"""

from ..backbones import available_backbones
from .encoder import LandmarkEncoder
from .projection import random_projection

__all__ = [
    "LandmarkEncoder",
    "available_backbones",
    "random_projection",
]
