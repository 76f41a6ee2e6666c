"""Several study notebooks in one kernel, the runner's child process (``python -m``): one kernel
start and one round of imports per dataset; before each notebook the kernel's namespace, figures
and inline format are reset (as a fresh kernel's)."""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

__all__ = ["RESET", "run_session"]

#: Run (unrecorded) before each notebook: a fresh kernel's namespace, counter, figures and
#: inline figure format (notebooks 01 and 06 switch theirs to JPEG).
RESET = """\
get_ipython().reset(new_session=True)
import matplotlib.pyplot as _plt
from matplotlib_inline.backend_inline import set_matplotlib_formats as _formats
_plt.close("all")
_formats("png")
del _plt, _formats
"""


def run_session(request: dict) -> None:
    """Execute ``request["notebooks"]`` (papermill keyword sets) in order in one kernel.

    Appends ``{"notebook": stem, "started": unix time}`` to ``request["status"]`` (JSON
    lines) when a notebook starts and ``{"done": stem, "ended": unix time}`` when it ends,
    so the caller can say what finished. ``request["nice"]`` (optional) lowers the CPU priority
    of this process and of the kernel it starts.

    Raises:
        RuntimeError: the kernel did not accept the reset (its reply names the error).
        papermill.PapermillExecutionError: a cell failed (the executed copy shows it).
    """
    import papermill as pm  # optional heavy dependencies: imported where used
    from jupyter_client.manager import AsyncKernelManager
    from jupyter_core.utils import run_sync

    if request.get("nice"):
        os.nice(int(request["nice"]))  # this process and the kernel it starts
    status = Path(request["status"])
    km = AsyncKernelManager(kernel_name=request["kernel"])
    run_sync(km.start_kernel)(cwd=request["cwd"])
    client = km.blocking_client()
    client.start_channels()
    try:
        client.wait_for_ready(timeout=120)
        for job in request["notebooks"]:
            stem = Path(job["input_path"]).stem
            with status.open("a") as f:
                f.write(json.dumps({"notebook": stem, "started": time.time()}) + "\n")
            reply = client.execute_interactive(
                RESET, store_history=False, timeout=120, output_hook=lambda msg: None
            )
            if reply["content"]["status"] != "ok":
                raise RuntimeError(f"resetting the kernel before {stem}: {reply['content']}")
            pm.execute_notebook(
                **job,
                kernel_name=request["kernel"],
                cwd=request["cwd"],
                progress_bar=request["progress_bar"],
                stdout_file=sys.stdout,
                stderr_file=sys.stderr,
                km=km,
            )
            with status.open("a") as f:
                f.write(json.dumps({"done": stem, "ended": time.time()}) + "\n")
    finally:
        client.stop_channels()
        run_sync(km.shutdown_kernel)(now=False)


if __name__ == "__main__":  # pragma: no cover - the runner's child process
    run_session(json.loads(sys.argv[1]))
