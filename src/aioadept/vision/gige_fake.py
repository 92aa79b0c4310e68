"""Aravis's fake GigE Vision camera (``Aravis.GvFakeCamera``) as a process, for tests and trials without hardware.

``python -m aioadept.vision.gige_fake [--address 127.0.0.1] [--serial S] [--trigger-hz 1000]`` serves real GVCP
(control, port 3956) and GVSP (stream) on ``--address`` only (the ``-i`` of Aravis's ``arv-fake-gv-camera``), prints
``READY address=...`` once it listens, and runs until SIGTERM/SIGINT. Its image is Aravis's test pattern. The fake
camera polls for software triggers at 25 Hz by default; ``--trigger-hz`` sets that poll rate (1 kHz: a trigger costs
at most 1 ms of waiting).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m aioadept.vision.gige_fake", description=__doc__.split("\n\n")[0])
    p.add_argument("--address", default="127.0.0.1", help="listen on this IPv4 address only (default 127.0.0.1)")
    p.add_argument("--serial", default="AIOADEPT0", help="serial number the camera reports")
    p.add_argument("--trigger-hz", type=float, default=1000.0, help="software-trigger poll rate (default 1000)")
    args = p.parse_args(argv)
    from aioadept.errors import VisionError
    from aioadept.vision.gige import load_aravis

    try:
        Aravis = load_aravis()
    except VisionError as exc:
        print(f"gige_fake: {exc}", file=sys.stderr)
        return 3
    cam = Aravis.GvFakeCamera.new(args.address, args.serial)
    if cam is None or not cam.is_running():
        print(f"gige_fake: cannot listen on {args.address}:3956 (in use, or not a local address)", file=sys.stderr)
        return 2
    cam.get_fake_camera().set_trigger_frequency(args.trigger_hz)
    done = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: done.set())
    print(f"READY address={args.address} serial={args.serial}", flush=True)
    while not done.wait(0.5):  # the camera runs in Aravis's own threads; this one only waits for the signal
        pass
    cam.run_dispose()
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
