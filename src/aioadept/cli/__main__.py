"""``python -m aioadept.cli``: the same as the ``aioadept`` console script."""

import sys

from aioadept.cli import main

sys.exit(main())
