"""Commands from OPC UA (``aioadept opcua --allow-commands``): who may call them, and what they do.

Off by default. With commands allowed, each MotionDevice gets two methods in the vendor namespace
:data:`VENDOR_NS`: ``Stop()`` and ``RunSkill(Skill, Arguments)``, each answering with the robot server's ack line.
They go through a :class:`~aioadept.client.RobotClient` of their own, like every other client, so a stop from OPC UA
is the protocol's stop (docs/protocol.md 4.2: acked at rest, for every connection) and a skill is sent once and never
again. Only a user named in the users file (``NAME:PASSWORD`` lines, readable by its owner only) may call them; an
anonymous session reads the cell and nothing more.
"""

from __future__ import annotations

import hmac
import os
import stat
from pathlib import Path

__all__ = ["VENDOR_NS", "RobotCommands", "read_users"]

VENDOR_NS = "urn:aioadept:opcua:commands"


def read_users(path: str | Path) -> dict[str, str]:
    """The users file: one ``NAME:PASSWORD`` a line (``#`` comments, blank lines skipped). ValueError naming the file
    and line for a line that is not one, a repeated name, no user at all, or a file others may read (a password
    file readable by the group or the world is refused, as ssh refuses such a key)."""
    p = Path(path)
    mode = os.stat(p).st_mode
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise ValueError(f"{p}: readable by others (mode {stat.filemode(mode)}): chmod 600 {p}")
    users: dict[str, str] = {}
    for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        name, sep, password = text.partition(":")
        if not sep or not name.strip() or not password:
            raise ValueError(f"{p}:{n}: expected NAME:PASSWORD")
        if name.strip() in users:
            raise ValueError(f"{p}:{n}: user {name.strip()!r} given twice")
        users[name.strip()] = password
    if not users:
        raise ValueError(f"{p}: no user (expected NAME:PASSWORD lines)")
    return users


def password_ok(users: dict[str, str], name: str | None, password: str | bytes | None) -> bool:
    """True when ``name`` is a user and ``password`` its password (compared in constant time)."""
    if name is None or password is None or name not in users:
        return False
    given = password.encode() if isinstance(password, str) else bytes(password)
    return hmac.compare_digest(given, users[name].encode())


class RobotCommands:
    """The methods' work on one robot server: its own RobotClient, connected on first use and again after a lost
    connection (a command is never sent again; only a stop whose connection was lost before its ack is, which
    cannot move the robot)."""

    def __init__(self, host: str, port: int) -> None:
        from aioadept.client import RobotClient

        self.robot = RobotClient(host, port, auto_reconnect=True, connect_timeout_s=2.0, ack_timeout_s=None)

    async def connect(self) -> None:
        """Connect now if not connected (the methods do it themselves; the server does it at start so the first
        stop does not wait for a connection)."""
        if not self.robot.connected:
            await self.robot.connect()

    async def stop(self) -> str:
        """Stop the robot; the stop's ack line once it is at rest. Raises as :meth:`RobotClient.stop`."""
        from aioadept.protocol import encode_ack

        await self.connect()
        result = await self.robot.stop()
        return encode_ack(result.ack).decode().strip()

    async def run_skill(self, name: str, args: list[float]) -> str:
        """Send ``name`` with ``args`` once; its ack line (``done``, or the ``error``/``aborted`` one). ValueError for
        a skill the protocol cannot carry; raises as :meth:`RobotClient.cmdexec` when no ack comes."""
        from aioadept.commands import Skill
        from aioadept.errors import CommandAborted, CommandError
        from aioadept.protocol import encode_ack

        command = Skill(name, *args)
        await self.connect()
        try:
            result = await self.robot.cmdexec(command)
        except (CommandError, CommandAborted) as exc:
            ack = getattr(exc, "ack", None)
            if ack is None:
                raise
            return encode_ack(ack).decode().strip()
        return encode_ack(result.messages[-1].ack).decode().strip()

    async def close(self) -> None:
        await self.robot.close()
