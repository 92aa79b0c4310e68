"""``python -m aioadept`` is the ``aioadept`` console script."""

import sys

from aioadept.cli import main

sys.exit(main())
