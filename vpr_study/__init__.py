"""The study's tooling on top of the pipeline (:mod:`vpr_core`): the ``vpr-study`` CLI, the notebook
runner and the findings table."""

__all__: list[str] = []
