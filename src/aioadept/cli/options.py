"""The options layer every subcommand shares: the help formatter, ``--config``, ``-v``, the robot address, the
ZeroMQ endpoints with their defaults (read from :mod:`aioadept.defaults`, never spelled out here), the cell options of
``demo``/``focus``/``experiment``, logging, and the one error-to-one-line handler (:func:`report`, the config
reader's).
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING

from aioadept import defaults
from aioadept.configfile import report

if TYPE_CHECKING:
    from aioadept.apps.cell import CellConfig

__all__ = ["DefaultsHelpFormatter", "ROBOT_HELP", "add_cell_options", "add_config", "add_verbose",
           "apply_overrides", "configure_logging", "description", "parse_robot_address", "report"]


def description(doc: str | None) -> str:
    """A module docstring's first paragraph as a subcommand's ``--help`` shows it: without ````literal```` markup."""
    return (doc or "").split("\n\n")[0].replace("``", "")


class DefaultsHelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Adds "(default: X)" to an option's help unless the help already says its default, or there is none."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "default" in text or action.default in (None, False, [], argparse.SUPPRESS):
            return text
        return super()._get_help_string(action)


def add_config(p: argparse.ArgumentParser, help: str, **kw) -> None:  # noqa: A002
    """``--config FILE``: a TOML file read with :func:`aioadept.configfile.load_toml`."""
    p.add_argument("--config", help=help, **kw)


def add_verbose(p: argparse.ArgumentParser) -> None:
    p.add_argument("-v", "--verbose", action="store_true")


ROBOT_HELP = (f"robot server HOST[:PORT] (default {defaults.ROBOT_HOST}:{defaults.ROBOT_PORT}; without a port: "
              f"{defaults.ROBOT_PORT})")


def parse_robot_address(text: str, default_port: int = defaults.ROBOT_PORT) -> tuple[str, int]:
    """``"HOST[:PORT]"`` -> ``(host, port)``; the port defaults to :data:`aioadept.defaults.ROBOT_PORT`;
    ValueError in one line otherwise."""
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = text, str(default_port)
    if not port.isdigit() or not 0 < int(port) <= 0xFFFF:
        raise ValueError(f"--robot {text!r}: expected HOST[:PORT] with PORT in 1..65535, "
                         f"e.g. {defaults.ROBOT_HOST}:{defaults.ROBOT_PORT}")
    return host or defaults.ROBOT_HOST, int(port)


def add_cell_options(p: argparse.ArgumentParser) -> None:
    add_config(p, "cell description (TOML); options below override it", type=Path)
    p.add_argument("--out", help="folder for run folders (default: runs)")
    p.add_argument("--speed", type=int, help="approach speed 0..100 (default 25)")
    p.add_argument("--delta-z", type=float, dest="delta_z", help="tool z step in mm (default 2.0)")
    p.add_argument("--max-steps", type=int, dest="max_steps", help="give up after this many steps (default 40)")
    p.add_argument("--vision-timeout", type=float, dest="vision_timeout", help="seconds per vision request")
    p.add_argument("--no-analyze", action="store_true", help="do not compute the timing analysis and plots")
    add_verbose(p)
    from aioadept.record.hook import add_view_options

    add_view_options(p)


def apply_overrides(cfg: "CellConfig", args: argparse.Namespace) -> "CellConfig":
    focus = cfg.focus
    if args.speed is not None:
        focus = dataclasses.replace(focus, approach_speed=args.speed)
    if args.delta_z is not None:
        focus = dataclasses.replace(focus, delta_z_mm=args.delta_z)
    if args.max_steps is not None:
        focus = dataclasses.replace(focus, max_steps=args.max_steps)
    if args.vision_timeout is not None:
        focus = dataclasses.replace(focus, vision_timeout_s=args.vision_timeout)
    cfg.focus = focus
    if args.out:
        cfg.run.out_dir = args.out
    if args.no_analyze:
        cfg.run.analyze = False
    if getattr(args, "no_record", False):
        cfg.run.record = False
    return cfg


def configure_logging(verbose: bool) -> None:
    import logging

    from rich.logging import RichHandler

    logging.basicConfig(level=logging.DEBUG if verbose else logging.INFO, format="%(message)s",
                        handlers=[RichHandler(show_path=False)])


def with_default(text: str, default: object) -> str:
    """An option's help ending in its default, for options whose default is applied later (a config file may set
    it), so argparse cannot show it: ``with_default("SUB for ...", defaults.REQUEST_ENDPOINT)``."""
    return f"{text} (default {default})"


def add_robot_option(p: argparse.ArgumentParser) -> None:
    """``--robot HOST[:PORT]``, read with :func:`parse_robot_address`."""
    p.add_argument("--robot", help=ROBOT_HELP)
