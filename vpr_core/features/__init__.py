"""Landmark descriptors: crops or RoI pooling -> CNN (or handcrafted) features -> projection.

``LandmarkEncoder(backbone, dim, seed, device, pooling)`` turns an image and its landmark boxes
into one descriptor per box (Sec. 2.1). One concept per file:

* :mod:`.encoder`: :class:`LandmarkEncoder` (the two pooling modes, projection, ``encode_global``),
* :mod:`.crops`: ``crop`` mode's box crops (kornia ``crop_and_resize``, anti-alias pyramid),
* :mod:`.roi`: ``roi`` mode's working-size image and bilinear RoIAlign,
* :mod:`.projection`: the Gaussian random projection.

Backbones are looked up by name in :mod:`vpr_core.backbones` (``available_backbones()``).
"""

from ..backbones import available_backbones, parse_backbone
from .crops import boxes_to_corners
from .encoder import DESCRIPTOR_VERSION, POOLING_MODES, LandmarkEncoder, default_input_size
from .projection import random_projection

__all__ = [
    "DESCRIPTOR_VERSION",
    "POOLING_MODES",
    "LandmarkEncoder",
    "available_backbones",
    "boxes_to_corners",
    "default_input_size",
    "parse_backbone",
    "random_projection",
]
