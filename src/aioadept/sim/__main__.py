"""``python -m aioadept.sim``: the same as ``aioadept sim`` (:mod:`aioadept.cli.sim`)."""

import sys

from aioadept.cli.sim import build_parser, main, options_from_args, run  # noqa: F401

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
