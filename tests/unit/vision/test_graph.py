"""CompGraph: validation errors, execution order, outputs and timing, drawing."""

from __future__ import annotations

import time

import pytest

from aioadept.errors import GraphError, VisionError
from aioadept.vision.graph import CompGraph, draw_graph, graph_layout


def _diamond(calls: list[str] | None = None) -> CompGraph:
    """x -> a -> y; y -> b -> (p, q); (p, q) -> c -> r, with frozen k. Functions listed out of order on purpose."""
    log = calls if calls is not None else []

    def a(x, k):
        log.append("a")
        return x + k

    def b(y):
        log.append("b")
        return y * 2, y * 3

    def c(p, q):
        log.append("c")
        return p + q

    return CompGraph({"c": c, "b": b, "a": a},
                     {"c": (("p", "q"), "r"), "b": ("y", ("p", "q")), "a": (("x", "k"), "y")},
                     frozen_tokens={"k": 1})


def test_runs_in_dependency_order_and_returns_every_token():
    calls: list[str] = []
    g = _diamond(calls)
    assert g.order == ("a", "b", "c")
    run = g.run(x=1)
    assert calls == ["a", "b", "c"]
    assert dict(run.tokens) == {"x": 1, "k": 1, "y": 2, "p": 4, "q": 6, "r": 10}
    assert g.free_tokens == ("x",) and g.output_tokens == ("r",)
    assert g.producer("p") == "b" and g.producer("x") is None


def test_records_time_per_function():
    def slow(x):
        t_end = time.perf_counter() + 0.02  # busy wait: a timing test must not depend on the scheduler's sleep
        while time.perf_counter() < t_end:
            pass
        return x

    g = CompGraph({"fast": lambda y: y, "slow": slow}, {"slow": ("x", "y"), "fast": ("y", "z")})
    run = g.run(x=3)
    assert list(run.node_time_s) == ["slow", "fast"]
    assert run.node_time_s["slow"] >= 0.02 > run.node_time_s["fast"]
    assert run.total_time_s >= sum(run.node_time_s.values())


def test_frozen_tokens_can_be_overridden_per_run_and_replaced():
    g = _diamond()
    assert g.run(x=1, k=10)["r"] == 5 * 11
    g2 = g.with_frozen(k=2)
    assert g2.run(x=1)["r"] == 15 and g.run(x=1)["r"] == 10  # the original is unchanged
    with pytest.raises(GraphError, match="not frozen"):
        g.with_frozen(x=3)


def test_cycle_is_reported_with_its_path():
    with pytest.raises(GraphError, match=r"cycle: (f -> g -> f|g -> f -> g)"):
        CompGraph({"f": lambda a: a, "g": lambda b: b, "h": lambda x: x},
                  {"h": ("x", "y"), "f": ("b", "a"), "g": ("a", "b")})


def test_self_loop_is_a_cycle():
    with pytest.raises(GraphError, match="cycle"):
        CompGraph({"f": lambda a: a}, {"f": ("a", "a")})


def test_token_produced_twice():
    with pytest.raises(GraphError, match="'y' is produced twice") as info:
        CompGraph({"f": lambda x: x, "g": lambda x: x}, {"f": ("x", "y"), "g": ("x", "y")})
    assert info.value.tokens == ("y",)


def test_frozen_token_produced_by_a_function():
    with pytest.raises(GraphError, match="frozen token 'k'"):
        CompGraph({"f": lambda x: x}, {"f": ("x", "k")}, frozen_tokens={"k": 1})


def test_function_and_io_must_match():
    with pytest.raises(GraphError, match=r"without func_io entry: \['g'\]"):
        CompGraph({"f": lambda x: x, "g": lambda x: x}, {"f": ("x", "y")})
    with pytest.raises(GraphError, match=r"without function: \['g'\]"):
        CompGraph({"f": lambda x: x}, {"f": ("x", "y"), "g": ("y", "z")})
    with pytest.raises(GraphError, match="not callable"):
        CompGraph({"f": 3}, {"f": ("x", "y")})
    with pytest.raises(GraphError, match="must be"):
        CompGraph({"f": lambda x: x}, {"f": "x"})


def test_missing_and_unknown_inputs_fail_before_anything_runs():
    calls: list[str] = []
    g = _diamond(calls)
    with pytest.raises(GraphError, match=r"missing input tokens \['x'\]"):
        g.run()
    with pytest.raises(GraphError, match=r"unknown input tokens \['xx'\]"):
        g.run(x=1, xx=2)
    assert calls == []


def test_wrong_output_arity():
    g = CompGraph({"f": lambda x: (x, x, x)}, {"f": ("x", ("a", "b"))})
    with pytest.raises(GraphError, match="tuple of 2 values"):
        g.run(x=1)


def test_function_errors_propagate_unchanged_with_a_note():
    def fails(x):
        raise VisionError("no object found")

    g = CompGraph({"ok": lambda x: x, "fails": fails}, {"ok": ("x", "y"), "fails": ("y", "z")})
    with pytest.raises(VisionError) as info:
        g.run(x=1)
    assert "in graph function 'fails'" in info.value.__notes__[0]


def test_layout_is_layered_along_the_data_flow():
    layout = graph_layout(_diamond())
    assert layout["t:x"][:2] == ("token", 0)
    assert layout["f:a"][:2] == ("func", 1)
    assert layout["t:k"][:2] == ("frozen", 0)  # directly above its consumer
    assert layout["t:y"][1] == 2 and layout["f:b"][1] == 3 and layout["f:c"][1] == 5 and layout["t:r"][1] == 6


def test_draw_writes_a_png(tmp_path):
    path = tmp_path / "g.png"
    draw_graph(_diamond(), str(path), title="diamond")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 2000
