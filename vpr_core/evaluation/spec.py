"""How a run is evaluated, as a value: :class:`Evaluation` (protocol, bootstrap resamples),
checked once when it is made, so a run that cannot be evaluated is refused before any work. The
ground truth (and its tolerance) is the dataset's, set when loading it."""

from __future__ import annotations

import dataclasses

from ..checks import check_bootstrap_memory, check_choice, check_int

__all__ = [
    "BOOTSTRAP_PROTOCOLS",
    "N_BOOTSTRAP",
    "PROTOCOLS",
    "Evaluation",
    "as_evaluation",
    "refuse_tolerance",
]

#: The PR protocols (docs/DEFINITIONS.md).
PROTOCOLS = ("ratio", "best_match", "vpr_bench", "multi_match")
#: The protocols with per-query decisions, so with bootstrap intervals.
BOOTSTRAP_PROTOCOLS = ("ratio", "best_match", "vpr_bench")
#: Bootstrap resamples of every interval and paired difference (the one home of this count).
N_BOOTSTRAP = 1000


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """The PR protocol of AUC and R@100P (:data:`~vpr_core.evaluation.PROTOCOLS`) and the
    bootstrap resamples of the intervals (0: none).

    No tolerance: a run is scored against its dataset's ground truth as loaded
    (``load_dataset(..., tolerance=N)``, or ``ds.with_tolerance(N)`` for frame-aligned truth);
    the Eq. (1) matrix cache does not depend on it, so a tolerance sweep reuses every matrix."""

    protocol: str = "ratio"
    n_bootstrap: int = N_BOOTSTRAP

    def __post_init__(self) -> None:
        check_choice(self.protocol, "protocol", PROTOCOLS)
        n = check_int(self.n_bootstrap, "n_bootstrap (resamples; 0: no intervals)", 0)
        object.__setattr__(self, "n_bootstrap", n)
        check_bootstrap_memory(n)
        if n:
            self.require_per_query("pass n_bootstrap=0, or ")

    def with_options(self, options: dict, where: str) -> Evaluation:
        """This evaluation with its fields given as keywords to ``where`` (a function's name)
        changed; a ``tolerance`` among them is refused naming the fix (it is the dataset's)."""
        refuse_tolerance(options, where)
        return dataclasses.replace(self, **options) if options else self

    def require_per_query(self, fix: str) -> None:
        """Refuse a protocol without per-query decisions (``multi_match``) where the bootstrap
        needs them; ``fix`` starts the remedy the message names before the valid protocols."""
        if self.protocol not in BOOTSTRAP_PROTOCOLS:
            raise ValueError(
                f"protocol {self.protocol!r} has no bootstrap intervals (it decides per pair, not "
                f"per query); {fix}a protocol of {', '.join(BOOTSTRAP_PROTOCOLS)}"
            )


def as_evaluation(evaluation: Evaluation | str) -> Evaluation:
    """An :class:`Evaluation`, or a protocol name with the default resamples (none for
    ``multi_match``, which has no intervals)."""
    if isinstance(evaluation, Evaluation):
        return evaluation
    return Evaluation(
        evaluation, n_bootstrap=N_BOOTSTRAP if evaluation in BOOTSTRAP_PROTOCOLS else 0
    )


def refuse_tolerance(options: dict, where: str) -> None:
    """Refuse a ``tolerance`` among a run's keyword ``options`` (TypeError naming the fix): the
    ground truth is the dataset's, so a tolerance is given when loading it. ``where``: the
    function named in the message."""
    if "tolerance" in options:
        t = options["tolerance"]
        raise TypeError(
            f"{where}(tolerance={t!r}): the tolerance belongs to the dataset's ground truth, "
            f"not to a run; load the dataset with tolerance={t!r} "
            f"(load_dataset(name, root, tolerance={t!r})), or ds.with_tolerance({t!r}) for a "
            "frame-aligned dataset; the Eq. (1) matrices are reused from the cache"
        )
