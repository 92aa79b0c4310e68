"""The run folder: what one run of an application leaves on disk, and how it is written and read back.

Modules: :mod:`~aioadept.runs.capture` (the timing recorder the client and the bus feed, the folder's format,
:func:`~aioadept.runs.capture.load_run`, and :func:`~aioadept.runs.capture.write_atomic`, through which every file
of a run folder is written) and :mod:`~aioadept.runs.folder` (saving a run's results and its errors into the
folder, or discarding it). The format and every column are in docs/timing-log.md.
"""
