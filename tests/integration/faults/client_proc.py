"""A RobotClient in a process of its own, for the fault matrix: the process can be killed (SIGKILL), paused
(SIGSTOP) or cut off from the network while it has commands in flight.

    python client_proc.py HOST PORT WAIT_ACKS SKILL[:A,B,...] ...

Writes every skill call in ONE write (``RobotClient.submit``), prints ``SENT id,id,...``, waits for the first
WAIT_ACKS acks, prints ``ACKED id=status ...``, then blocks until it is killed. Errors go to stderr, exit code 1.
"""

from __future__ import annotations

import asyncio
import sys

from aioadept.client import RobotClient
from aioadept.protocol import SkillCall


def parse_call(text: str) -> SkillCall:
    skill, _, args = text.partition(":")
    return SkillCall(skill, tuple(float(a) if "." in a else int(a) for a in args.split(",")) if args else ())


async def main(host: str, port: int, wait_acks: int, calls: list[SkillCall]) -> None:
    async with RobotClient(host, port, ack_timeout_s=None, max_pending=None) as robot:  # floods on purpose
        sub = robot.submit(*calls)
        print("SENT " + ",".join(sub.ids), flush=True)
        assert sub.futures is not None
        acked = [await f for f in sub.futures[:wait_acks]]
        print("ACKED " + " ".join(f"{r.id}={r.ack.status.value}" for r in acked), flush=True)
        await asyncio.Event().wait()  # hold the connection until killed


if __name__ == "__main__":
    host, port, wait_acks, *specs = sys.argv[1:]
    asyncio.run(main(host, int(port), int(wait_acks), [parse_call(s) for s in specs]))
