"""``python -m aioadept.analysis``: the same as ``aioadept analyze`` (:mod:`aioadept.cli.analyze`)."""

import sys

from aioadept.cli.analyze import main  # noqa: F401

__all__ = ["main"]

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
