"""Read a ``run.rrd`` back as plain Python values, through Rerun's own reader (``rerun.chunk.RrdReader``).

For tests and quick checks, not for big recordings: every row of every entity is materialised.

    rows = read_rrd("runs/.../run.rrd")
    rows["/focus/sharpness"]          # [{"time": 1.7e9, "step": 0, "Scalars:scalars": [12.5]}, ...]
"""

from __future__ import annotations

import os
from collections import defaultdict
from typing import Any

__all__ = ["blueprint_views", "entity_paths", "read_rrd"]


def _column(col: Any) -> list[Any]:
    import pyarrow as pa

    if pa.types.is_timestamp(col.type) or pa.types.is_duration(col.type):
        return [None if v is None else v / 1e9 for v in col.cast(pa.int64()).to_pylist()]
    return col.to_pylist()


def read_rrd(path: str | os.PathLike[str]) -> dict[str, list[dict[str, Any]]]:
    """Entity path -> its rows in file order. Each row maps ``time`` (epoch s), ``step``, ``log_time`` (epoch s) and
    each component column (``Archetype:component``, its list value) to the value; the row id is left out.
    Static rows have no time. Rows of one entity are sorted by ``time`` when they have one."""
    import rerun as rr

    out: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for chunk in rr.chunk.RrdReader(os.fspath(path)).stream():
        batch = chunk.to_record_batch()
        names = [n for n in batch.schema.names if n != "rerun.controls.RowId"]
        cols = {n: _column(batch.column(n)) for n in names}
        for i in range(batch.num_rows):
            out[chunk.entity_path].append({n: cols[n][i] for n in names})
    for rows in out.values():
        rows.sort(key=lambda r: (r.get("time") is None, r.get("time") or 0.0))
    return dict(out)


def entity_paths(path: str | os.PathLike[str]) -> set[str]:
    """The entity paths that have at least one row."""
    return set(read_rrd(path))


def blueprint_views(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """The views of the file's default blueprint (the viewer's layout), each as ``{"kind", "origin", "name"}``
    (``kind`` is Rerun's view class: ``3D``, ``2D``, ``TextLog``, ``TimeSeries``); ``[]`` when it has none."""
    import rerun as rr

    reader = rr.chunk.RrdReader(os.fspath(path))
    views = []
    for store in reader.blueprints():
        for chunk in reader.stream(store=store):
            if chunk.entity_path.count("/") != 2 or not chunk.entity_path.startswith("/view/"):
                continue  # /view/<id> holds the view itself; /view/<id>/ViewContents its query
            batch = chunk.to_record_batch()
            cols = {n.split(":")[-1]: batch.column(n).to_pylist() for n in batch.schema.names if ":" in n}
            for i in range(batch.num_rows):
                views.append({"kind": _cell(cols, "class_identifier", i), "origin": _cell(cols, "space_origin", i),
                              "name": _cell(cols, "display_name", i)})
    return views


def _cell(cols: dict[str, list], name: str, i: int) -> Any:
    """Row ``i`` of column ``name``, a one-item list unwrapped (None when the file has no such column)."""
    v = cols[name][i] if name in cols else None
    return v[0] if isinstance(v, list) and v else v
