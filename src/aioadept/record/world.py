"""The simulated world in a run's recording (``run.rrd``) and the live view: the table, feeder, pallet and camera
once, then every part in 3D at each ``world.state`` sample (boxes and cylinders in their colours, grasped ones
labelled), the world's events in the message log (a drop as an error), and the fixed camera's view of the parts.

Entities (beside :class:`aioadept.record.rrd.CellLogger`'s; mm, base frame, timeline ``time``):

=======================  ===================================================================================
``world/table``          static: the table top, a thin grey plate under the parts, feeder and pallet
``world/feeder``         static: the feeder's rectangle (its sensor's input number as label)
``world/pallet``         static: the pallet's slots (points, numbered)
``world/parts/<id>``     each part: its frame (Transform3D) and its shape in it, labelled when grasped/dropped
``world/camera``         static: the world camera's frame and Pinhole (its frustum in 3D)
``world/camera/image``   what that camera sees (the sim's render, sharp, downsampled), at most
                         :data:`IMAGE_RATE_HZ` and at every grasp or release
``messages/world``       the world's events (grasped, released, dropped: an ERROR, sensor)
=======================  ===================================================================================
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from aioadept.world import WorldConfig

IMAGE_RATE_HZ = 2.0
"""World camera images logged per second at most (each is a render: a few ms of the recording thread)."""
_IMAGE_MAX_WIDTH = 320
_TABLE_MARGIN_MM = 100.0


class WorldLogger:
    """Logs a world's samples (:class:`aioadept.bus.messages.WorldState`) into the Rerun stream ``rec``."""

    def __init__(self, rec: Any, world: WorldConfig) -> None:
        import rerun as rr

        self.rr = rr
        self.rec = rec
        self.world = world
        self.counts = {"world": 0, "world_image": 0}
        self._last_image_t = -math.inf
        self._view = None
        if world.camera is not None:
            from aioadept.vision.world_camera import WorldView

            self._view = WorldView(world)
        self._setup()

    def _setup(self) -> None:
        rr, rec, w = self.rr, self.rec, self.world
        xs = [p.x_mm for p in w.parts] + ([w.feeder.x_mm] if w.feeder else []) + ([w.pallet.x_mm] if w.pallet else [])
        ys = [p.y_mm for p in w.parts] + ([w.feeder.y_mm] if w.feeder else []) + ([w.pallet.y_mm] if w.pallet else [])
        if w.pallet is not None:
            slots = [w.pallet.slot_xy(i)[:2] for i in range(w.pallet.slots)]
            xs += [s[0] for s in slots]
            ys += [s[1] for s in slots]
            rec.log("world/pallet", rr.Points3D([(x, y, w.table_z_mm + 0.5) for x, y in slots], radii=4.0,
                                                colors=[(60, 60, 60)], labels=[str(i) for i in range(len(slots))]),
                    static=True)
        if xs:
            x0, x1 = min(xs) - _TABLE_MARGIN_MM, max(xs) + _TABLE_MARGIN_MM
            y0, y1 = min(ys) - _TABLE_MARGIN_MM, max(ys) + _TABLE_MARGIN_MM
            rec.log("world/table", rr.Boxes3D(centers=[((x0 + x1) / 2, (y0 + y1) / 2, w.table_z_mm - 2.0)],
                                              half_sizes=[((x1 - x0) / 2, (y1 - y0) / 2, 2.0)],
                                              colors=[(200, 200, 196)]), static=True)
        if w.feeder is not None:
            f = w.feeder
            rec.log("world/feeder", rr.Boxes3D(centers=[(f.x_mm, f.y_mm, w.table_z_mm + 1.0)],
                                               half_sizes=[(f.width_mm / 2, f.depth_mm / 2, 1.0)],
                                               colors=[(240, 160, 40)], fill_mode="MajorWireframe",
                                               labels=[f"feeder (sensor {f.sensor})"]), static=True)
        self._drawn: set[int] = set()
        for p in w.parts:
            if not p.fed:  # a part the feeder's queue brings is drawn when it arrives (else it sits at the origin)
                self._draw_part(p)
        if self._view is not None:
            v = self._view
            pose = v.camera_pose
            rec.log("world/camera", rr.Transform3D(translation=pose.position_mm, mat3x3=pose.to_matrix()[:3, :3]),
                    static=True)
            cam = w.camera
            assert cam is not None
            scale = 1
            while cam.width_px // scale > _IMAGE_MAX_WIDTH:
                scale *= 2
            k = v.camera_matrix.copy()
            k[:2] /= scale
            rec.log("world/camera/image", rr.Pinhole(image_from_camera=k, width=cam.width_px // scale,
                                                     height=cam.height_px // scale,
                                                     camera_xyz=rr.ViewCoordinates.RDF, image_plane_distance=150.0),
                    static=True)
            self._scale = scale

    def _draw_part(self, p: Any) -> None:
        rr, rec = self.rr, self.rec
        self._drawn.add(p.id)
        path = f"world/parts/{p.id}"
        h = p.height_mm
        if p.shape == "cylinder":
            rec.log(path, rr.Cylinders3D(lengths=[h], radii=[p.size_mm[0] / 2], centers=[(0.0, 0.0, h / 2)],
                                         colors=[p.colour], fill_mode="Solid"), static=True)
        else:
            rec.log(path, rr.Boxes3D(half_sizes=[(p.size_mm[0] / 2, p.size_mm[1] / 2, h / 2)],
                                     centers=[(0.0, 0.0, h / 2)], colors=[p.colour], fill_mode="Solid"),
                    static=True)

    def state(self, ws: Any) -> None:
        """One ``world.state`` sample: the parts, the events, and (rate-limited) the camera's view."""
        rr, rec = self.rr, self.rec
        if not math.isfinite(ws.wall_time_s):
            return
        rec.set_time("time", timestamp=ws.wall_time_s)
        self.counts["world"] += 1
        for p in ws.parts:
            if p.id not in self._drawn:
                try:
                    self._draw_part(self.world.part(p.id))
                except KeyError:
                    continue  # not a part of this cell's world
            m = p.pose.to_matrix()
            rec.log(f"world/parts/{p.id}", rr.Transform3D(translation=m[:3, 3], mat3x3=m[:3, :3]))
        for e in ws.events:
            text = e.text or (f"part {e.part} {e.kind}" if e.kind != "sensor" else
                              f"sensor {e.signal} {'on' if e.on else 'off'}")
            rec.log("messages/world", rr.TextLog(text, level="ERROR" if e.kind == "dropped" else "INFO"))
        moved = any(e.kind in ("grasped", "released", "dropped", "fed") for e in ws.events)
        if self._view is not None and (moved or ws.wall_time_s - self._last_image_t >= 1.0 / IMAGE_RATE_HZ):
            self._last_image_t = ws.wall_time_s
            img = self._view.render_colour(ws.parts)[::self._scale, ::self._scale]
            rec.log("world/camera/image", rr.Image(np.ascontiguousarray(img), color_model="BGR")
                    .compress(jpeg_quality=85))
            self.counts["world_image"] += 1


__all__ = ["IMAGE_RATE_HZ", "WorldLogger"]
