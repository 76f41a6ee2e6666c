"""Named difficulty settings of the generator (presets as data, DESIGN.md section 5)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from ...checks import check_choice, check_int, check_range

__all__ = ["DIFFICULTIES", "SyntheticDifficulty", "resolve_difficulty"]

Range = tuple[float, float]
#: The settings that are probabilities (in [0, 1]).
_PROBABILITIES = ("day_occluder", "style_share", "repeat_facades", "lit_windows")


@dataclass(frozen=True)
class SyntheticDifficulty:
    """How hard the day-reference / night-query pairs of the synthetic route are.

    Ranges are ``(low, high)`` and drawn uniformly per place.

    Attributes:
        shift: Lateral offset between the two traverses, fraction of the image width (the query
            walks on the other side of the path).
        zoom: Query zoom factor (``> 1``: closer).
        rotation_deg: Maximum absolute query roll, degrees (the reference rolls by at most 1).
        keystone: Query perspective (relative height difference of the view's left / right edges).
        vertical: Maximum vertical offset of the query view, fraction of the image height.
        occluders: ``(min, max)`` pedestrians / cars in a night query (inclusive).
        day_occluder: Probability of one occluder in a day reference.
        style_share: Probability that a building takes its style from the route-wide style bank.
        repeat_facades: Probability that a building is an exact copy (windows, signs, posters) of
            one of ``facade_pool`` buildings shared by the whole route: perceptual aliasing.
        facade_pool: Number of shared buildings.
        night_ambient: Night exposure range (fraction of the day brightness).
        night_gamma: Gamma of the night tone curve (``> 1`` darkens mid-tones).
        lit_windows: Probability that a window is lit at night.
        glow: Strength of the lamp / window glare.
        noise: Night sensor noise, standard deviation range (``[0, 1]`` intensity units).
        blur: Night blur sigma range in pixels at 360 px image height.
    """

    shift: Range = (0.10, 0.22)
    zoom: Range = (0.85, 1.15)
    rotation_deg: float = 5.0
    keystone: Range = (0.02, 0.07)
    vertical: float = 0.05
    occluders: tuple[int, int] = (1, 2)
    day_occluder: float = 0.35
    style_share: float = 0.8
    repeat_facades: float = 0.0
    facade_pool: int = 8
    night_ambient: Range = (0.3, 0.5)
    night_gamma: float = 1.15
    lit_windows: float = 0.35
    glow: float = 0.4
    noise: Range = (0.02, 0.04)
    blur: Range = (0.5, 1.0)

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v, name = getattr(self, f.name), f"SyntheticDifficulty.{f.name}"
            if isinstance(v, tuple):
                if len(v) != 2 or not v[0] <= v[1] or min(v) < 0:
                    raise ValueError(
                        f"{name} must be a (low, high) pair with 0 <= low <= high, got {v!r}."
                    )
            else:
                check_range(v, name, 0, 1 if f.name in _PROBABILITIES else math.inf)
        check_range(self.zoom[0], "SyntheticDifficulty.zoom (low)", 0, low_open=True)
        check_int(self.facade_pool, "SyntheticDifficulty.facade_pool", minimum=1)
        check_range(self.night_gamma, "SyntheticDifficulty.night_gamma", 0, low_open=True)

    def as_dict(self) -> dict:
        """Plain JSON-able dict (for cache keys and manifests)."""
        return {
            k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()
        }


#: Named presets. ``easy`` is the generator of SYNTHETIC_VERSION 5 (saturated: most methods
#: reach AUC ~1); ``default`` is calibrated by ``benchmarks/calibrate_synthetic.py`` (numbers in
#: docs/SYNTHETIC.md); ``hard`` goes further on every axis.
DIFFICULTIES: dict[str, SyntheticDifficulty] = {
    "easy": SyntheticDifficulty(),
    "default": SyntheticDifficulty(
        shift=(0.18, 0.33),
        zoom=(0.78, 1.26),
        rotation_deg=7.5,
        keystone=(0.045, 0.11),
        vertical=0.075,
        occluders=(1, 3),
        day_occluder=0.5,
        style_share=0.9,
        repeat_facades=0.45,
        facade_pool=5,
        night_ambient=(0.3, 0.5),
        night_gamma=1.15,
        lit_windows=0.35,
        glow=0.45,
        noise=(0.025, 0.045),
        blur=(0.6, 1.1),
    ),
    "hard": SyntheticDifficulty(
        shift=(0.22, 0.38),
        zoom=(0.72, 1.32),
        rotation_deg=9.0,
        keystone=(0.06, 0.13),
        vertical=0.09,
        occluders=(2, 4),
        day_occluder=0.6,
        style_share=1.0,
        repeat_facades=0.55,
        facade_pool=5,
        night_ambient=(0.2, 0.35),
        night_gamma=1.3,
        lit_windows=0.3,
        glow=0.55,
        noise=(0.035, 0.06),
        blur=(0.8, 1.4),
    ),
}


def resolve_difficulty(difficulty: str | SyntheticDifficulty) -> tuple[str, SyntheticDifficulty]:
    """``(name, settings)`` of a preset name or a :class:`SyntheticDifficulty`.

    A custom :class:`SyntheticDifficulty` equal to a preset gets that preset's name, else
    ``"custom"``.

    Raises:
        ValueError: unknown name (the message lists the valid ones).
        TypeError: neither a name nor a :class:`SyntheticDifficulty`.
    """
    if isinstance(difficulty, SyntheticDifficulty):
        for name, preset in DIFFICULTIES.items():
            if preset == difficulty:
                return name, preset
        return "custom", difficulty
    if isinstance(difficulty, str):
        key = check_choice(difficulty.strip().lower(), "synthetic difficulty", DIFFICULTIES)
        return key, DIFFICULTIES[key]
    raise TypeError(
        f"synthetic: difficulty must be a name ({', '.join(DIFFICULTIES)}) or a "
        f"SyntheticDifficulty, got {type(difficulty).__name__}."
    )
