"""``python -m aioadept.vision``: the same as ``aioadept vision`` (:mod:`aioadept.cli.vision`)."""

import sys

from aioadept.cli.vision import main

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
