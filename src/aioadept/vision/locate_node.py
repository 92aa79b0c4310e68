"""The part locator as a processing node: a ``LocateRequest`` in, the parts in robot base coordinates out.

Where it sits: the same node as the sharpness service (:class:`aioadept.vision.node.VisionNode`: the frame for the
request's time from the acquisition ring, the stale-frame and stale-state checks, where the graph runs, the
Responder and its limits), with the locator graph (:func:`aioadept.vision.locate.locate_graph`) and its own
answer. Serve it with :func:`locate_responder` (a :class:`~aioadept.vision.node.NodeResponder` for
``LocateRequest`` events).

Request attributes (all optional; docs/vision.md, "Part locator"):

- ``t_request`` (DOUBLE, epoch s) and ``camera`` (STRING): as for ``VisionRequest``;
- ``marker`` (INT): only the part with this ArUco id; ``colour`` (STRING): look for parts of this colour (a name of
  :data:`aioadept.vision.locate.COLOURS`; with ``height_mm``), and answer only those;
- ``height_mm`` (DOUBLE): height of the parts' top faces above the table; ``marker_mm`` (DOUBLE): the markers'
  side; ``corners`` (INT 1): add each marker's image corners (for the calibration routine).

Answer: ``parts`` (INT) and ``part.<i>.*`` (:func:`aioadept.bus.located.parts_to_attributes`), ``proc_time_ms``
and the frame attributes of every vision answer; or ``error`` (a bad request, an unknown colour, no frame ...). Zero
parts found is an answer (``parts = 0``), not an error: whether that is a fault is the requester's call.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from aioadept.bus.located import LOCATE_REQUEST, parts_to_attributes
from aioadept.vision.acquisition import Acquisition
from aioadept.vision.calibration import CameraCalibration
from aioadept.vision.graph import CompGraph
from aioadept.vision.locate import COLOURS, locate, locate_graph
from aioadept.vision.node import NodeResponder, VisionNode
from aioadept.errors import BadLocateRequest


def _number(attributes: Mapping[str, Any], key: str, lo: float, hi: float) -> float | None:
    value = attributes.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or not lo <= value <= hi:
        raise BadLocateRequest(f"bad request: {key} = {value!r}: expected a number in {lo:g}..{hi:g}")
    return float(value)


def request_overrides(attributes: Mapping[str, Any]) -> tuple[dict[str, Any], int | None, str | None, bool]:
    """(graph overrides, marker filter, colour filter, corners wanted) of a request's attributes; raises
    :class:`BadLocateRequest` naming the attribute."""
    overrides: dict[str, Any] = {}
    height = _number(attributes, "height_mm", -1000.0, 2000.0)
    if height is not None:
        overrides["height_mm"] = height
    side = _number(attributes, "marker_mm", 0.1, 1000.0)
    if side is not None:
        overrides["marker_mm"] = side
    marker = attributes.get("marker")
    if marker is not None and (isinstance(marker, bool) or not isinstance(marker, int) or marker < 0):
        raise BadLocateRequest(f"bad request: marker = {marker!r}: expected an ArUco id (an integer >= 0)")
    colour = attributes.get("colour")
    if colour is not None:
        if not isinstance(colour, str) or colour not in COLOURS:
            shown = repr(colour)[:40]
            raise BadLocateRequest(f"bad request: colour = {shown}: expected one of {', '.join(COLOURS)}")
        overrides["colours"] = (colour,)
    corners = attributes.get("corners", 0)
    if corners not in (0, 1) or isinstance(corners, (bool, float)):
        raise BadLocateRequest(f"bad request: corners = {corners!r}: expected 0 or 1")
    return overrides, marker, colour, bool(corners)


class LocatorNode(VisionNode):
    """A :class:`VisionNode` answering locate requests with ``graph`` (default: :func:`locate_graph` of
    ``calibration`` with ``hyperparameters``); the other options are :class:`VisionNode`'s."""

    def __init__(self, acquisition: Acquisition, calibration: CameraCalibration, graph: CompGraph | None = None, *,
                 hyperparameters: Mapping[str, Any] | None = None, **options: Any) -> None:
        self.calibration = calibration
        super().__init__(acquisition, graph if graph is not None else
                         locate_graph(calibration, **dict(hyperparameters or {})), **options)

    def analyse(self, image: Any, attributes: Mapping[str, Any]) -> dict[str, Any]:
        try:
            overrides, marker, colour, corners = request_overrides(attributes)
        except BadLocateRequest as exc:
            return {"proc_time_ms": 0.0, "error": str(exc)}
        res = locate(image, self.graph, **overrides)
        if not res.ok:
            return {"proc_time_ms": res.proc_time_ms, "error": res.error}
        parts = [p for p in res.parts if (marker is None or p.marker == marker)
                 and (colour is None or p.colour == colour)]
        if not corners:
            import dataclasses

            parts = [dataclasses.replace(p, corners_px=()) for p in parts]
        return {"proc_time_ms": res.proc_time_ms, **parts_to_attributes(parts)}

    def describe(self, out: Mapping[str, Any]) -> str:
        found = ", ".join(
            f"{out.get(f'part.{i}.marker', out.get(f'part.{i}.colour', '?'))}@({out[f'part.{i}.x_mm']:.1f}, "
            f"{out[f'part.{i}.y_mm']:.1f}, {out[f'part.{i}.yaw_deg']:.1f} deg)" for i in range(int(out["parts"])))
        return f"parts={out['parts']} [{found}] frame_t={out['frame_t']:.3f} proc={out['proc_time_ms']:.2f} ms"


def locate_responder(request_endpoint: str, response_endpoint: str, node: LocatorNode,
                     **options: Any) -> NodeResponder:
    """The Responder serving ``node``: ``LocateRequest`` events only (answered ``LocateResponse``)."""
    options.setdefault("request_types", (LOCATE_REQUEST,))
    return NodeResponder(request_endpoint, response_endpoint, node, **options)


__all__ = ["LocatorNode", "locate_responder", "request_overrides"]
