"""free_port hands out ports that outgoing connections never take."""

import socket

from aioadept import ports


def test_a_picked_port_lies_outside_the_ephemeral_range_and_is_bindable():
    lo, hi = ports._ephemeral_range()
    for _ in range(20):
        port = ports.free_port()
        assert not lo <= port <= hi
        with socket.socket() as s:
            s.bind(("127.0.0.1", port))


def test_a_taken_port_is_never_picked(monkeypatch):
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        held.listen()
        taken = held.getsockname()[1]
        picks = iter([taken, taken])
        real_choice = ports.random.choice
        monkeypatch.setattr(ports.random, "choice", lambda pool: next(picks, None) or real_choice(pool))
        assert ports.free_port() != taken
        assert next(picks, None) is None  # both picks of the taken port were tried
