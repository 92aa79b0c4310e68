"""The documentation site builds from the repository, and no link in it or in the README is broken.

`make docs` runs `mkdocs build --strict` (mkdocs.yml): every warning, including a link to a page or an anchor that
does not exist, fails the build. These tests run the same build into a temporary folder, check that the strict
link validation really fails on a broken link, and check the README's relative links, which MkDocs does not see.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MKDOCS = [sys.executable, "-m", "mkdocs"]
ENV = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
# [text](target) and ![alt](target), not inside inline code; the target ends at whitespace or ')'.
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def _build(config: Path, site: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*MKDOCS, "build", "--strict", "--config-file", str(config), "--site-dir", str(site)],
                          cwd=config.parent, env=ENV, capture_output=True, text=True, timeout=240)


@pytest.mark.timeout(300)
def test_the_site_builds_strictly_with_every_page_and_the_api_reference(tmp_path: Path) -> None:
    res = _build(ROOT / "mkdocs.yml", tmp_path / "site")
    assert res.returncode == 0, res.stderr[-4000:]
    site = tmp_path / "site"
    for page in ("index", "getting-started", "focus", "troubleshooting", "protocol", "vplus", "sim", "vision"):
        assert (site / f"{page}.html").is_file(), page
    # The API reference is generated from the docstrings: a class of each module is on its page.
    for page, name in [("client", "RobotClient"), ("commands", "MoveToolZ"), ("errors", "CommandError"),
                       ("protocol", "LineFramer"), ("sim", "SimServer"), ("bus", "Communicator"),
                       ("vision", "VisionNode"), ("apps", "CellConfig"), ("testing", "ScriptedServer")]:
        html = (site / "api" / f"{page}.html").read_text(encoding="utf-8")
        assert f'id="aioadept.{page}' in html, page
        assert name in html, (page, name)
    # The V+ emulator and the run.rrd reader have pages too, with their public names documented.
    for page, ids in [("vplus", ["aioadept.vplus.Emulator", "aioadept.vplus.Emulator.load"]),
                      ("record", ["aioadept.record.read.read_rrd", "aioadept.record.read.blueprint_views"])]:
        html = (site / "api" / f"{page}.html").read_text(encoding="utf-8")
        for anchor in ids:
            assert f'id="{anchor}"' in html, (page, anchor)
    # Nothing is fetched from the internet when a page is shown: no web fonts, no scripts or styles from a CDN.
    for html_file in site.rglob("*.html"):
        html = html_file.read_text(encoding="utf-8")
        assert not re.search(r"<(script|link)[^>]+(src|href)=\"(https?:)?//", html), html_file
        assert "fonts.googleapis" not in html, html_file


@pytest.mark.timeout(120)
def test_strict_validation_fails_on_a_link_to_a_missing_page_or_anchor(tmp_path: Path) -> None:
    # The same validation rules as the real site, on a two-page site, so the check is known to bite.
    import yaml

    real = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "index.md").write_text("# Home\n\nSee [the other page](other.md#there).\n", encoding="utf-8")
    (docs / "other.md").write_text("# Other\n\n## There\n", encoding="utf-8")
    config = tmp_path / "mkdocs.yml"
    config.write_text(yaml.safe_dump({"site_name": "t", "validation": real["validation"],
                                      "markdown_extensions": ["toc"]}), encoding="utf-8")
    assert _build(config, tmp_path / "site").returncode == 0

    (docs / "index.md").write_text("# Home\n\nSee [a page](missing.md).\n", encoding="utf-8")
    res = _build(config, tmp_path / "site")
    assert res.returncode != 0 and "missing.md" in res.stderr

    (docs / "index.md").write_text("# Home\n\nSee [the other page](other.md#nowhere).\n", encoding="utf-8")
    res = _build(config, tmp_path / "site")
    assert res.returncode != 0 and "nowhere" in res.stderr


def _relative_links(md: Path) -> list[str]:
    text = re.sub(r"```.*?```", "", md.read_text(encoding="utf-8"), flags=re.S)   # code blocks are not links
    text = re.sub(r"`[^`\n]*`", "", text)
    return [t for t in LINK.findall(text) if not re.match(r"[a-z]+:", t) and not t.startswith("#")]


@pytest.mark.parametrize("md", [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_points_to_a_file_that_exists(md: Path) -> None:
    broken = [t for t in _relative_links(md) if not (md.parent / t.split("#")[0]).exists()]
    assert not broken, f"{md.relative_to(ROOT)} links to missing files: {broken}"


def test_the_built_site_is_not_committed() -> None:
    ignored = subprocess.run(["git", "check-ignore", "-q", "site/index.html"], cwd=ROOT)
    assert ignored.returncode == 0, "site/ is not in .gitignore"


def test_troubleshooting_covers_every_error_a_user_can_meet() -> None:
    # Every exception of the one error tree, and every exit status the commands document, has its entry.
    import inspect

    import aioadept.errors as errors

    page = (ROOT / "docs" / "troubleshooting.md").read_text(encoding="utf-8")
    names = [n for n, obj in vars(errors).items()
             if inspect.isclass(obj) and issubclass(obj, errors.AdeptError) and obj is not errors.AdeptError
             and obj.__module__ == errors.__name__ and n not in ("ProtocolError",)]
    missing = [n for n in names if f"`{n}`" not in page]
    assert not missing, f"docs/troubleshooting.md does not explain {missing}"
    for status in (0, 1, 2, 3, 4, 130):
        assert re.search(rf"^\| {status} \|", page, re.M), status


@pytest.mark.timeout(90)
def test_the_getting_started_client_example_runs_against_the_simulator_as_documented() -> None:
    page = (ROOT / "docs" / "getting-started.md").read_text(encoding="utf-8")
    (code,) = re.findall(r"```python\n(.*?)```", page, re.S)
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr[-3000:]
    lines = res.stdout.splitlines()
    assert [ln.split()[:2] for ln in lines[:3]] == [["set_speed", "done"], ["move_rel_tool", "done"],
                                                   ["break", "done"]]
    assert lines[3].startswith("at rest in Pose(")
    assert lines[4].startswith("refused: -610 ")     # the page promises the sim's out-of-reach error ack


def test_the_cell_file_page_documents_every_key_and_no_other() -> None:
    import dataclasses

    from aioadept.cell.config import CellConfig

    page = (ROOT / "docs" / "focus.md").read_text(encoding="utf-8")
    for section in dataclasses.fields(CellConfig):
        if section.name == "world":  # optional; its keys are documented in docs/sim.md (test_world_docs)
            assert "**`[world]`**" in page and "sim.md#the-world" in page
            continue
        if section.name == "calibration":  # optional (None by default): the keys of its own table
            from aioadept.vision.calibration import CameraCalibration

            keys = {f.name for f in dataclasses.fields(CameraCalibration)}
        else:
            keys = {f.name for f in dataclasses.fields(getattr(CellConfig(), section.name))}
        block = page.split(f"**`[{section.name}]`**", 1)[1].split("\n\n", 2)[1]     # the section's key table
        documented = {k for cell in re.findall(r"^\| ([^|]+) \|", block, re.M) for k in re.findall(r"`(\w+)`", cell)}
        assert documented == keys, (section.name, documented ^ keys)


def test_world_docs_name_every_key_of_the_world_table() -> None:
    import dataclasses

    from aioadept.cell import world as world_tables

    page = (ROOT / "docs" / "sim.md").read_text(encoding="utf-8")
    section = page.split("## The world", 1)[1].split("\n## ", 1)[0]
    for table in (world_tables._WorldTable, world_tables._PartTable, world_tables._FeederTable,
                  world_tables._PalletTable, world_tables._CameraTable):
        missing = [f.name for f in dataclasses.fields(table) if not re.search(rf"\b{f.name}\b", section)]
        assert not missing, (table.__name__, missing)
