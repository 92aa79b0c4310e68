"""Compatibility: the options shared by ``demo``, ``focus`` and ``experiment`` are in :mod:`aioadept.cli.options`,
the terminal report of a run in :mod:`aioadept.cli.report`."""

from aioadept.cli.options import add_cell_options, apply_overrides, configure_logging  # noqa: F401
from aioadept.cli.report import EXIT_NOT_SAVED, print_result, report_saving  # noqa: F401
