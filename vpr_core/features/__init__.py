"""Landmark descriptors: ``LandmarkEncoder`` (:mod:`.encoder`), ``crop`` mode's crops
(:mod:`.crops`), ``roi`` mode's RoIAlign (:mod:`.roi`), the random projection (:mod:`.projection`);
backbones in :mod:`vpr_core.backbones`."""

from ..backbones import available_backbones
from .encoder import Encoder, LandmarkEncoder, as_encoder
from .stage import encoder_slug, extract_features, get_encoder

__all__ = [
    "Encoder",
    "LandmarkEncoder",
    "as_encoder",
    "available_backbones",
    "encoder_slug",
    "extract_features",
    "get_encoder",
]
