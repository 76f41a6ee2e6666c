"""How a run is evaluated, as a value: :class:`Evaluation` (protocol, bootstrap resamples),
checked once when it is made, so a run that cannot be evaluated is refused before any work."""

from __future__ import annotations

import dataclasses

from ..checks import check_choice, check_int
from .bootstrap import BOOTSTRAP_PROTOCOLS, N_BOOTSTRAP
from .curves import PROTOCOLS

__all__ = ["Evaluation"]


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """The PR protocol of AUC and R@100P (:data:`~vpr_core.evaluation.PROTOCOLS`) and the
    bootstrap resamples of the intervals (0: none). The ground-truth tolerance is the dataset's
    (applied when it is loaded, ``load_dataset(..., tolerance=N)``)."""

    protocol: str = "ratio"
    n_bootstrap: int = N_BOOTSTRAP

    def __post_init__(self) -> None:
        check_choice(self.protocol, "protocol", PROTOCOLS)
        n = check_int(self.n_bootstrap, "n_bootstrap (resamples; 0: no intervals)", 0)
        object.__setattr__(self, "n_bootstrap", n)
        if n and self.protocol not in BOOTSTRAP_PROTOCOLS:
            raise ValueError(
                f"protocol {self.protocol!r} has no bootstrap intervals (it decides per pair, not "
                f"per query); pass n_bootstrap=0, or a protocol of "
                f"{', '.join(BOOTSTRAP_PROTOCOLS)}"
            )
