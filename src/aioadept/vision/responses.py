"""Vision's reading of the bus's answers: a node's ``error`` result becomes :class:`~aioadept.errors.VisionError`.

The bus (:mod:`aioadept.bus`) knows nothing of its users: it returns a :class:`~aioadept.bus.Response` and, asked
to, raises its own :class:`~aioadept.errors.RemoteError`. A MasterControlNode talking to a vision node wants
the vision error instead::

    from aioadept.vision import raise_for_error
    resp = raise_for_error(await comm.request("VisionRequest"))   # VisionError if the node answered ``error``
"""

from __future__ import annotations

from aioadept.errors import RemoteError
from aioadept.bus.pairing import Response
from aioadept.errors import VisionError

__all__ = ["as_vision_error", "raise_for_error"]


def as_vision_error(exc: RemoteError) -> VisionError:
    """The :class:`VisionError` for a vision node's error answer (same text and attributes)."""
    err = VisionError(str(exc), attributes=exc.attributes)
    return err


def raise_for_error(response: Response) -> Response:
    """Return ``response``, or raise :class:`VisionError` (with the attributes) if the node answered with an
    ``error``: a failed measurement (no object found), a dropped or bad request, a stale robot state."""
    try:
        return response.raise_for_error()
    except RemoteError as exc:
        raise as_vision_error(exc) from exc
