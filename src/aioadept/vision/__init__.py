"""The vision side of the cell: acquisition (FxIS-style ring buffers), the EPypes-style computational graph, the
paper's sharpness pipeline, camera sources (virtual camera on the simulated robot, image folders, OpenCV capture)
and the processing node behind ``aioadept vision``. See docs/vision.md.

Data path::

    Camera.grab() -> Acquisition (one thread per source, FrameRing) -> VisionNode (frame for t_request)
        -> CompGraph.run(image=...) -> response attributes -> bus Responder

Names are imported lazily so ``import aioadept.vision`` stays cheap (OpenCV loads on first use).
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "CompGraph": "graph", "GraphRun": "graph", "draw_graph": "graph",
    "sharpness_graph": "sharpness", "measure": "sharpness", "SharpnessResult": "sharpness",
    "Region": "sharpness", "DEFAULT_HYPERPARAMETERS": "sharpness",
    "Camera": "sources", "Frame": "sources", "ImageFolderSource": "sources", "OpenCVSource": "sources",
    "FrameRecorder": "sources",
    "VirtualCamera": "virtual_camera", "LensOptics": "virtual_camera", "CalibrationTarget": "virtual_camera",
    "PoseHistory": "virtual_camera", "RobotStateFollower": "virtual_camera", "paper_camera": "virtual_camera",
    "paper_approach_pose": "virtual_camera", "camera_facing_tool": "virtual_camera",
    "Acquisition": "acquisition", "FrameRing": "acquisition",
    "VisionNode": "node", "noop_graph": "node",
    "locate_graph": "locate", "LocatorNode": "locate_node", "CameraCalibration": "calibration",
    "calibrate_eye_to_hand": "calibration",
    "write_figures": "figures",
    "raise_for_error": "responses",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'aioadept.vision' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"aioadept.vision.{module}"), name)
    globals()[name] = value
    return value
