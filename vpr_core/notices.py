"""Warnings that change what a number means: logged on ``vpr_core`` and raised as VPRWarning
(filter them with ``warnings.simplefilter("ignore", VPRWarning)``)."""

from __future__ import annotations

import logging
import warnings

__all__ = ["VPRWarning", "notice"]

logger = logging.getLogger("vpr_core")


class VPRWarning(UserWarning):
    """A library warning that changes what a reported number means."""


def notice(message: str, stacklevel: int = 3) -> str:
    """Log ``message`` (what happened, what it changes, the fix) on the ``vpr_core`` logger and
    raise it as a :class:`VPRWarning` (``stacklevel`` 3: the caller of ``notice``'s caller);
    returns it, so a caller can also record it (e.g. on a result's ``.warnings``)."""
    logger.warning(message)
    warnings.warn(message, VPRWarning, stacklevel=stacklevel)
    return message
