"""``aioadept vision --figures``: the Fig. 7-9 pictures are written and are PNGs."""

from __future__ import annotations

from aioadept.cli.vision import main


def test_figures_command_writes_three_pngs(tmp_path, capsys):
    assert main(["--figures", str(tmp_path)]) == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["sharpness_graph.png", "sharpness_intermediate.png", "sharpness_sweep.png"]
    for p in tmp_path.iterdir():
        assert p.read_bytes()[:4] == b"\x89PNG" and 10_000 < p.stat().st_size < 300_000
    assert capsys.readouterr().out.count(".png") == 3
