"""Compatibility: ``aioadept focus`` is :mod:`aioadept.cli.focus`."""

import sys

from aioadept.cli.focus import build_parser, main  # noqa: F401
from aioadept.cli.options import parse_robot_address  # noqa: F401

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
