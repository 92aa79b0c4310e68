"""The part locator's answer on the wire (docs/vision.md, "Part locator"): located parts <-> flat EPypes attributes.

A ``LocateRequest`` is an EPypes ``Event`` like every vision request, and its ``LocateResponse`` carries the parts as
flat attributes (:func:`parts_to_attributes`), so any EPypes node, the Responder, the recording and the timing logs
carry it unchanged; the Protobuf schema is :mod:`aioadept.bus.messages`'.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from aioadept.bus.messages import AttributeValue
from aioadept.errors import BusError

__all__ = ["LOCATE_REQUEST", "LocatedPart", "parts_from_attributes", "parts_to_attributes"]

LOCATE_REQUEST = "LocateRequest"
"""The event type of a part locator request (answered by a ``LocateResponse``; docs/vision.md, "Part locator")."""


@dataclass(frozen=True, slots=True)
class LocatedPart:
    """One part the locator found, in robot base coordinates: the centre of its top face (``x_mm, y_mm, z_mm``),
    its turn about the base z axis (``yaw_deg``), and what identifies it: ``kind`` ``"marker"`` (``marker``: the
    ArUco id) or ``"colour"`` (``colour``: the colour name; ``length_mm``/``width_mm``: the top face's sides).
    ``corners_px``: a marker's four image corners (cv2.aruco's order, 8 numbers), when the request asked for them."""

    x_mm: float
    y_mm: float
    z_mm: float
    yaw_deg: float
    kind: str = "marker"
    marker: int | None = None
    colour: str = ""
    length_mm: float | None = None
    width_mm: float | None = None
    corners_px: tuple[float, ...] = ()


_PART_FLOATS = ("x_mm", "y_mm", "z_mm", "yaw_deg", "length_mm", "width_mm")


def parts_to_attributes(parts: Sequence[LocatedPart]) -> dict[str, AttributeValue]:
    """A locate answer's parts as flat EPypes attributes: ``parts`` (INT, the count) and per part ``i``
    ``part.<i>.<field>`` (DOUBLE for lengths and angles, INT ``marker``, STRING ``kind``/``colour``,
    ``corners_px`` as a STRING of 8 comma-separated numbers). Flat attributes, not a nested message, so the answer
    travels as every other vision response does (an EPypes ``Event``: any EPypes node can read it, and the
    Responder, the requester, the recording and the timing logs carry it unchanged)."""
    out: dict[str, AttributeValue] = {"parts": len(parts)}
    for i, p in enumerate(parts):
        pre = f"part.{i}."
        for name in _PART_FLOATS:
            value = getattr(p, name)
            if value is not None:
                out[pre + name] = float(value)
        out[pre + "kind"] = p.kind
        if p.marker is not None:
            out[pre + "marker"] = int(p.marker)
        if p.colour:
            out[pre + "colour"] = p.colour
        if p.corners_px:
            out[pre + "corners_px"] = ",".join(f"{v:.3f}" for v in p.corners_px)
    return out


def parts_from_attributes(attributes: Mapping[str, Any]) -> tuple[LocatedPart, ...]:
    """The parts of a ``LocateResponse``'s attributes (:func:`parts_to_attributes` read back); :class:`BusError`
    when the count or a part's position is missing or of the wrong type."""
    n = attributes.get("parts")
    if isinstance(n, bool) or not isinstance(n, int) or n < 0:
        raise BusError(f"locate response: parts = {n!r}: expected the number of parts found")
    out = []
    for i in range(n):
        pre = f"part.{i}."
        try:
            floats = {name: attributes.get(pre + name) for name in _PART_FLOATS}
            for name in ("x_mm", "y_mm", "z_mm", "yaw_deg"):
                floats[name] = float(floats[name])  # type: ignore[arg-type]
            corners = attributes.get(pre + "corners_px")
            out.append(LocatedPart(
                kind=str(attributes.get(pre + "kind", "")), marker=attributes.get(pre + "marker"),
                colour=str(attributes.get(pre + "colour", "")),
                corners_px=tuple(float(v) for v in corners.split(",")) if corners else (), **floats))
        except (TypeError, ValueError) as exc:
            raise BusError(f"locate response: part {i}: {exc}") from None
    return tuple(out)
