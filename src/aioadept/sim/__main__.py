"""``python -m aioadept.sim``: the same as ``aioadept sim`` (:mod:`aioadept.cli.sim`)."""

import sys

from aioadept.cli.sim import main

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
