"""EPypes-style computational graphs: image processing as a bipartite DAG of functions and data tokens.

A graph is given the way EPypes gives it (Semeniuta & Falkman 2019):

- ``func_dict``: function name -> callable;
- ``func_io``: function name -> ``(input tokens, output tokens)``; a single output may be a plain string (the
  function returns one value), several outputs are a tuple (the function returns a tuple of that length);
- ``frozen_tokens``: token -> value, the hyperparameters (shaded in the paper's Fig. 7).

Tokens that are consumed but neither produced nor frozen are the graph's *free* inputs (``image`` for the sharpness
graph); :meth:`CompGraph.run` must be given them. Everything is checked when the graph is built, so a bad graph fails
at start-up, not on the first frame:

- every function has an io entry and every io entry a function;
- no token is produced by two functions, and no frozen token is produced by a function;
- no cycle.

The runner executes functions in a fixed dependency order, returns every token and the time spent in each function.
:func:`draw_graph` draws the graph like Fig. 7: functions as boxes, tokens as ellipses, frozen tokens shaded.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from aioadept.errors import GraphError


@dataclass(frozen=True, slots=True)
class GraphRun:
    """The result of one :meth:`CompGraph.run`.

    ``tokens`` holds every token (free inputs, frozen values, all outputs); ``node_time_s`` the wall time of each
    function in execution order (``time.perf_counter`` differences, s); ``total_time_s`` the whole run.
    """

    tokens: Mapping[str, Any]
    node_time_s: Mapping[str, float]
    total_time_s: float

    def __getitem__(self, token: str) -> Any:
        return self.tokens[token]


def _as_tuple(tokens: str | Sequence[str]) -> tuple[str, ...]:
    if isinstance(tokens, str):
        return (tokens,)
    return tuple(tokens)


@dataclass(frozen=True, slots=True)
class _Node:
    name: str
    func: Callable[..., Any]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    single_output: bool  # func_io gave a plain string: the return value is the token, not a tuple to unpack


@dataclass(frozen=True, slots=True, eq=False)
class CompGraph:
    """A validated computational graph. Build with ``CompGraph(func_dict, func_io, frozen_tokens=...)``.

    Raises :class:`aioadept.errors.GraphError` when the description is inconsistent (see the module docstring).
    Instances are immutable; :meth:`with_frozen` returns a copy with changed hyperparameters.
    """

    func_dict: Mapping[str, Callable[..., Any]]
    func_io: Mapping[str, tuple[str | Sequence[str], str | Sequence[str]]]
    frozen_tokens: Mapping[str, Any] = field(default_factory=dict)
    name: str = "graph"
    _nodes: tuple[_Node, ...] = field(init=False, repr=False)
    _producer: Mapping[str, str] = field(init=False, repr=False)
    _free: frozenset[str] = field(init=False, repr=False)      # free tokens, for run()'s input check
    _allowed: frozenset[str] = field(init=False, repr=False)   # free + frozen: the names run() accepts

    def __post_init__(self) -> None:
        # Freeze the caller's dicts so a running node cannot be changed under it.
        object.__setattr__(self, "func_dict", MappingProxyType(dict(self.func_dict)))
        object.__setattr__(self, "func_io", MappingProxyType(dict(self.func_io)))
        object.__setattr__(self, "frozen_tokens", MappingProxyType(dict(self.frozen_tokens)))
        nodes, producer = _validate(self.func_dict, self.func_io, self.frozen_tokens)
        object.__setattr__(self, "_nodes", nodes)
        object.__setattr__(self, "_producer", MappingProxyType(producer))
        # Computed once: run() checks its inputs against them on every call (the latency path of a vision node).
        object.__setattr__(self, "_free", frozenset(self.free_tokens))
        object.__setattr__(self, "_allowed", self._free | frozenset(self.frozen_tokens))

    # ----------------------------------------------------------------------------------------------- structure
    @property
    def order(self) -> tuple[str, ...]:
        """Function names in the order the runner executes them (a topological order, stable in input order)."""
        return tuple(n.name for n in self._nodes)

    @property
    def tokens(self) -> frozenset[str]:
        """Every token the graph mentions."""
        out: set[str] = set(self.frozen_tokens)
        for n in self._nodes:
            out.update(n.inputs)
            out.update(n.outputs)
        return frozenset(out)

    @property
    def free_tokens(self) -> tuple[str, ...]:
        """Inputs that :meth:`run` must be given: consumed, not produced, not frozen (sorted)."""
        consumed = {t for n in self._nodes for t in n.inputs}
        return tuple(sorted(t for t in consumed if t not in self._producer and t not in self.frozen_tokens))

    @property
    def output_tokens(self) -> tuple[str, ...]:
        """Tokens produced by a function and consumed by none (the graph's results), in execution order."""
        consumed = {t for n in self._nodes for t in n.inputs}
        return tuple(t for n in self._nodes for t in n.outputs if t not in consumed)

    def producer(self, token: str) -> str | None:
        """Name of the function producing ``token``, or None for a free or frozen token."""
        return self._producer.get(token)

    def io(self, func_name: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(inputs, outputs) of one function."""
        for n in self._nodes:
            if n.name == func_name:
                return n.inputs, n.outputs
        raise KeyError(func_name)

    def with_frozen(self, **values: Any) -> CompGraph:
        """A copy with some frozen tokens replaced; unknown names raise :class:`GraphError`."""
        unknown = sorted(set(values) - set(self.frozen_tokens))
        if unknown:
            raise GraphError(f"{self.name}: not frozen tokens: {unknown}")
        return CompGraph(self.func_dict, self.func_io, frozen_tokens={**self.frozen_tokens, **values},
                         name=self.name)

    # ----------------------------------------------------------------------------------------------- running
    def run(self, **inputs: Any) -> GraphRun:
        """Execute every function once in dependency order and return all tokens with per-function times.

        ``inputs`` must give every free token; it may also override frozen tokens for this run. Missing free
        tokens or unknown names raise :class:`GraphError` before anything runs. An exception raised by a function
        propagates unchanged, with a note naming the function (so ``VisionError`` from a step reaches the caller
        as itself). A function returning the wrong number of outputs raises :class:`GraphError`.
        """
        names = inputs.keys()
        if not self._free <= names <= self._allowed:  # one set comparison on the common path; details if not
            missing = [t for t in self.free_tokens if t not in inputs]
            if missing:
                raise GraphError(f"{self.name}: missing input tokens {missing}", tokens=tuple(missing))
            unknown = sorted(names - self._allowed)
            raise GraphError(f"{self.name}: unknown input tokens {unknown}", tokens=tuple(unknown))
        tokens: dict[str, Any] = {**self.frozen_tokens, **inputs}
        times: dict[str, float] = {}
        t_run = time.perf_counter()
        for node in self._nodes:
            args = [tokens[t] for t in node.inputs]
            t0 = time.perf_counter()
            try:
                result = node.func(*args)
            except Exception as exc:
                exc.add_note(f"in {self.name} function {node.name!r}")
                raise
            times[node.name] = time.perf_counter() - t0
            if node.single_output:
                tokens[node.outputs[0]] = result
            else:
                if not isinstance(result, tuple) or len(result) != len(node.outputs):
                    got = len(result) if isinstance(result, tuple) else type(result).__name__
                    raise GraphError(f"{self.name}: function {node.name!r} must return a tuple of "
                                     f"{len(node.outputs)} values {node.outputs}, got {got}")
                tokens.update(zip(node.outputs, result, strict=True))
        total = time.perf_counter() - t_run
        return GraphRun(tokens=MappingProxyType(tokens), node_time_s=MappingProxyType(times), total_time_s=total)


def _validate(func_dict: Mapping[str, Callable[..., Any]],
              func_io: Mapping[str, tuple[Any, Any]],
              frozen: Mapping[str, Any]) -> tuple[tuple[_Node, ...], dict[str, str]]:
    no_io = [f for f in func_dict if f not in func_io]
    no_func = [f for f in func_io if f not in func_dict]
    if no_io or no_func:
        raise GraphError(f"functions without func_io entry: {no_io}; func_io entries without function: {no_func}")
    nodes: list[_Node] = []
    producer: dict[str, str] = {}
    for name, io in func_io.items():
        if not callable(func_dict[name]):
            raise GraphError(f"func_dict[{name!r}] is not callable")
        try:
            ins, outs = io
        except (TypeError, ValueError):
            raise GraphError(f"func_io[{name!r}] must be (inputs, outputs), got {io!r}") from None
        single = isinstance(outs, str)
        ins_t, outs_t = _as_tuple(ins), _as_tuple(outs)
        if not outs_t:
            raise GraphError(f"function {name!r} produces no token")
        if len(set(outs_t)) != len(outs_t):
            raise GraphError(f"function {name!r} lists an output token twice: {outs_t}")
        for t in outs_t:
            if t in producer:
                raise GraphError(f"token {t!r} is produced twice: by {producer[t]!r} and {name!r}", tokens=(t,))
            if t in frozen:
                raise GraphError(f"frozen token {t!r} is also produced by {name!r}", tokens=(t,))
            producer[t] = name
        nodes.append(_Node(name, func_dict[name], ins_t, outs_t, single))

    # Kahn's algorithm; among ready functions take the earliest in func_io order so the order is reproducible.
    deps = {n.name: {producer[t] for t in n.inputs if t in producer} for n in nodes}
    by_name = {n.name: n for n in nodes}
    ordered: list[_Node] = []
    done: set[str] = set()
    pending = [n.name for n in nodes]
    while pending:
        ready = next((f for f in pending if deps[f] <= done), None)
        if ready is None:
            cycle = _find_cycle(deps, pending)
            raise GraphError(f"the graph has a cycle: {' -> '.join(cycle)}", tokens=())
        pending.remove(ready)
        done.add(ready)
        ordered.append(by_name[ready])
    return tuple(ordered), producer


def _find_cycle(deps: Mapping[str, set[str]], pending: Sequence[str]) -> list[str]:
    """One cycle among ``pending`` functions (each has an unfinished dependency), as a closed path of names."""
    left = set(pending)
    path: list[str] = [pending[0]]
    seen = {pending[0]: 0}
    while True:
        nxt = sorted(d for d in deps[path[-1]] if d in left)[0]
        if nxt in seen:
            cycle = path[seen[nxt]:] + [nxt]
            cycle.reverse()  # deps point upstream; print the data flow direction
            return cycle
        seen[nxt] = len(path)
        path.append(nxt)


# --------------------------------------------------------------------------------------------------- drawing
def graph_layout(graph: CompGraph) -> dict[str, tuple[str, int, int]]:
    """Layered layout of the bipartite graph for drawing: node key -> (kind, layer, position in layer).

    Keys are ``"f:NAME"`` for functions and ``"t:NAME"`` for tokens; kinds ``"func"``, ``"token"``, ``"frozen"``.
    Free tokens sit in layer 0, a function one layer below its deepest input, its outputs one below it, and a
    frozen token directly above its first consumer (as in Fig. 7, where hyperparameters feed in from the side).
    """
    layer: dict[str, int] = {}
    kind: dict[str, str] = {}
    for t in graph.free_tokens:
        layer[f"t:{t}"], kind[f"t:{t}"] = 0, "token"
    for fname in graph.order:
        ins, outs = graph.io(fname)
        dyn = [layer[f"t:{t}"] for t in ins if t not in graph.frozen_tokens]
        fl = (max(dyn) + 1) if dyn else 1
        layer[f"f:{fname}"], kind[f"f:{fname}"] = fl, "func"
        for t in ins:
            if t in graph.frozen_tokens and f"t:{t}" not in layer:
                layer[f"t:{t}"], kind[f"t:{t}"] = fl - 1, "frozen"
        for t in outs:
            layer[f"t:{t}"], kind[f"t:{t}"] = fl + 1, "token"
    for t in graph.frozen_tokens:  # frozen but unused: still show it
        if f"t:{t}" not in layer:
            layer[f"t:{t}"], kind[f"t:{t}"] = 0, "frozen"
    # Within a layer: data tokens and functions first (the main flow), frozen tokens to the right.
    rows: dict[int, list[str]] = {}
    for key in layer:
        rows.setdefault(layer[key], []).append(key)
    out: dict[str, tuple[str, int, int]] = {}
    for lay, keys in rows.items():
        keys.sort(key=lambda k: kind[k] == "frozen")
        for i, k in enumerate(keys):
            out[k] = (kind[k], lay, i)
    return out


def draw_graph(graph: CompGraph, path: str | None = None, *, ax: Any = None, title: str | None = None,
               dpi: int = 110) -> Any:
    """Draw ``graph`` like the paper's Fig. 7 and return the matplotlib Figure.

    Functions are boxes, tokens ellipses, frozen tokens shaded grey; edges point along the data flow. With
    ``path`` the figure is saved there (PNG by extension) and closed. matplotlib is imported here, lazily.
    """
    import matplotlib

    if ax is None and path is not None:
        matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    layout = graph_layout(graph)
    n_layers = max(lay for _, lay, _ in layout.values()) + 1
    width = max(sum(1 for _, lay, _ in layout.values() if lay == L) for L in range(n_layers))
    if ax is None:
        fig, ax = plt.subplots(figsize=(2.9 * max(width, 2) + 1.0, 0.62 * n_layers + 0.6))
    else:
        fig = ax.figure
    ax.set_axis_off()
    ax.set_xlim(-1.0, 1.35 * (max(width, 2) - 1) + 0.6)
    ax.set_ylim(-n_layers + 0.5, 0.5)
    texts: dict[str, Any] = {}
    for key, (kind, lay, pos) in layout.items():
        label = key[2:]
        if kind == "func":
            style = dict(boxstyle="square,pad=0.35", fc="white", ec="black", lw=1.2)
        elif kind == "frozen":
            style = dict(boxstyle="ellipse,pad=0.25", fc="#c8c8c8", ec="black", lw=0.9)
        else:
            style = dict(boxstyle="ellipse,pad=0.25", fc="white", ec="black", lw=0.9)
        texts[key] = ax.text(pos * 1.35, -lay, label, ha="center", va="center", fontsize=9, family="monospace",
                             bbox=style, zorder=3)
    from matplotlib.patches import FancyArrowPatch

    for fname in graph.order:
        ins, outs = graph.io(fname)
        fkey = f"f:{fname}"
        for src, dst in [(f"t:{t}", fkey) for t in ins] + [(fkey, f"t:{t}") for t in outs]:
            (x0, y0), (x1, y1) = texts[src].get_position(), texts[dst].get_position()
            # An edge skipping layers would run through the nodes between: route it as a bracket on the left.
            if abs(y1 - y0) > 1.5 and abs(x1 - x0) < 0.5:
                conn = "arc,angleA=180,angleB=180,armA=95,armB=95,rad=8"
            else:
                conn = "arc3,rad=0.0"
            ax.add_patch(FancyArrowPatch((x0, y0), (x1, y1), arrowstyle="-|>", mutation_scale=11, lw=0.9,
                                         color="black", patchA=texts[src].get_bbox_patch(),
                                         patchB=texts[dst].get_bbox_patch(), shrinkA=1, shrinkB=1,
                                         connectionstyle=conn, zorder=4))
    if title:
        ax.set_title(title, fontsize=10)
    if path is not None:
        fig.savefig(path, dpi=dpi, bbox_inches="tight")
        plt.close(fig)
    return fig
