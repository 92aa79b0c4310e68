"""Pictures of the vision side, like the paper's Figs. 7-9: ``aioadept vision --figures OUTDIR``.

- ``sharpness_graph.png``: the computational graph (Fig. 7): functions as boxes, tokens as ellipses, frozen
  hyperparameters shaded;
- ``sharpness_intermediate.png``: for five positions of the calibration object around the focal plane, ordered by
  decreasing distance to the camera (poses 1..5, pose 3 in focus), the cropped image, the ``sobelx_im`` token and the
  ``profile_sx`` token (Fig. 8);
- ``sharpness_sweep.png``: sharpness after each ``MoveToolZ(+delta_z)`` step from the approach pose, with the
  configured focal plane marked (Fig. 9).

All frames come from the default virtual camera (:func:`aioadept.vision.virtual_camera.paper_camera`), rendered at
poses computed directly, so no robot or bus is needed. matplotlib is imported here only.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from aioadept.geometry import Pose
from aioadept.vision.sharpness import sharpness_graph
from aioadept.vision.virtual_camera import paper_approach_pose, paper_camera


def write_figures(outdir: str | Path, *, focus_offset_mm: float = 20.0, delta_z_mm: float = 2.0,
                  fig8_step_mm: float = 2.5, n_steps: int = 20, seed: int = 1, dpi: int = 90) -> list[Path]:
    """Write the three figures into ``outdir`` (created) and return their paths.

    ``fig8_step_mm``: spacing of the five Fig. 8 positions around the focal plane; ``delta_z_mm`` and ``n_steps``:
    the sweep of Fig. 9.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from aioadept.vision.graph import draw_graph

    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    graph = sharpness_graph()
    cam = paper_camera(focus_offset_mm=focus_offset_mm, seed=seed)
    approach = paper_approach_pose()
    paths: list[Path] = []

    p = out / "sharpness_graph.png"
    draw_graph(graph, str(p), title="sharpness measurement (cf. Fig. 7)", dpi=dpi)
    paths.append(p)

    # Fig. 8: poses 1..5 in decreasing distance to the camera, pose 3 on the focal plane.
    offsets = [focus_offset_mm + k * fig8_step_mm for k in (-2, -1, 0, 1, 2)]
    fig, axes = plt.subplots(3, 5, figsize=(13, 6.2), gridspec_kw={"height_ratios": [1, 1, 0.8]})
    profiles = []
    for col, dz in enumerate(offsets):
        pose = approach @ Pose(z=dz)
        run = graph.run(image=cam.render(pose))
        roi, sx, prof = run["roi"], run["sobelx_im"], run["profile_sx"]
        profiles.append(prof)
        dist = cam.object_distance_mm(pose)
        axes[0, col].imshow(cv2.resize(roi, (320, max(1, round(roi.shape[0] * 320 / roi.shape[1]))),
                                       interpolation=cv2.INTER_AREA), cmap="gray", vmin=0, vmax=255,
                            interpolation="nearest")
        axes[0, col].axhline(roi.shape[0] // 2 * 320 / roi.shape[1], color="tab:red", lw=0.6)
        axes[0, col].set_title(f"pose {col + 1}: {dist:.1f} mm\nsharpness {run['sharpness']:.1f}", fontsize=9)
        # Shrink by area averaging before display: thin gradient lines would alias at figure resolution.
        shown = cv2.resize(sx, (320, max(1, round(sx.shape[0] * 320 / sx.shape[1]))), interpolation=cv2.INTER_AREA)
        axes[1, col].imshow(shown, cmap="RdBu_r", vmin=-300, vmax=300, interpolation="nearest")
        axes[1, col].set_title("sobelx_im (blue < 0 < red)", fontsize=8)
        for ax in axes[:2, col]:
            ax.set_xticks([])
            ax.set_yticks([])
    lim = max(float(np.abs(pr).max()) for pr in profiles) * 1.05
    for col, prof in enumerate(profiles):
        ax = axes[2, col]
        ax.plot(prof, lw=0.6, color="black")
        ax.set_ylim(-lim, lim)
        ax.set_title("profile_sx", fontsize=8)
        ax.tick_params(labelsize=7)
        if col:
            ax.set_yticklabels([])
    fig.suptitle("roi (red: the profile row), sobelx_im and profile_sx at 5 object distances "
                 "(focal plane at pose 3; cf. Fig. 8)", fontsize=10)
    fig.tight_layout()
    p = out / "sharpness_intermediate.png"
    fig.savefig(p, dpi=round(dpi * 0.85))  # the widest figure: keep the PNG small
    plt.close(fig)
    paths.append(p)

    # Fig. 9: the sweep the focus application performs.
    zs = [i * delta_z_mm for i in range(n_steps + 1)]
    values = [graph.run(image=cam.render(approach @ Pose(z=z)))["sharpness"] for z in zs]
    fig, ax = plt.subplots(figsize=(6.4, 3.4))
    ax.plot(range(len(zs)), values, "o-", color="tab:blue", ms=4)
    ax.axvline(focus_offset_mm / delta_z_mm, color="tab:red", lw=1, label="configured focal plane")
    ax.set_xlabel(f"step (MoveToolZ +{delta_z_mm:g} mm from the approach pose)")
    ax.set_ylabel("sharpness (std of profile_sx)")
    ax.set_title("sharpness over a z sweep, virtual camera (cf. Fig. 9)", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    p = out / "sharpness_sweep.png"
    fig.savefig(p, dpi=dpi)
    plt.close(fig)
    paths.append(p)
    return paths
