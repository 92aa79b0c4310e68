"""``python -m aioadept.vision``: the same as ``aioadept vision`` (:mod:`aioadept.cli.vision`)."""

import sys

from aioadept.cli.vision import build_parser, load_config, main, resolve_options  # noqa: F401
from aioadept.vision.service import _state_curve, make_sources, serve  # noqa: F401

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
