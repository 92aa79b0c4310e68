"""Compatibility: ``aioadept send`` is :mod:`aioadept.cli.send`; ``python -m aioadept.client_cli`` still works."""

import sys

from aioadept.cli.send import main, parse_skill  # noqa: F401

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
