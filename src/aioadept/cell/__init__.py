"""The cell file: its schema and how it is read. A cell file is one TOML file describing a cell (the robot, the
vision node, the focus and pick-and-place parameters, the simulated world, the bus); every ``--config`` reads it.

Modules: :mod:`~aioadept.cell.schema` (the TOML reader, typed sections and value ranges, the one-line error
report), :mod:`~aioadept.cell.config` (the single-robot file: :class:`~aioadept.cell.config.CellConfig`),
:mod:`~aioadept.cell.multi` (``[[robots]]``/``[[cameras]]``: several robots in one cell), :mod:`~aioadept.cell.bus`
(``[bus]``: the transport and the cell's keys), :mod:`~aioadept.cell.world` (``[world]``: the simulated world).
The applications that run a cell are in :mod:`aioadept.apps`.
"""
