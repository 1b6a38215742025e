"""docs/format.md, the format reference, is right about what crashstudy accepts.

Every ```yaml block of the page parses; every block marked ``<!-- example: model FILE, N nodes, S springs -->``
or ``<!-- example: study FILE, N variants -->`` is written to FILE and passes ``crashstudy validate`` with
the counts the marker (and the text) states. The complete frontal model is run and holds the numbers the
page quotes. No tracked file points outside the repository (to the product contract a clone does not have).
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

from crashstudy.cli.main import main
from crashstudy.schema import load_model
from crashstudy.schema.yamlio import loads_yaml
from crashstudy.study.plan import load_study
from helpers import ROOT

DOC = ROOT / "docs" / "format.md"
BLOCK = re.compile(r"(?:<!-- example: (?P<marker>[^>]*?) -->\n)?```yaml\n(?P<body>.*?)```", re.S)
MODEL = re.compile(r"model (?P<file>\S+\.yaml), (?P<nodes>\d+) nodes, (?P<springs>\d+) springs")
STUDY = re.compile(r"study (?P<file>\S+\.yaml), (?P<variants>\d+) variants")


def _blocks() -> list[tuple[str | None, str]]:
    return [(m["marker"], m["body"]) for m in BLOCK.finditer(DOC.read_text(encoding="utf-8"))]


def _examples(tmp_path: Path) -> tuple[dict[str, re.Match[str]], dict[str, re.Match[str]]]:
    """Write every marked block to its file in ``tmp_path``; return the model and study markers by file."""
    models: dict[str, re.Match[str]] = {}
    studies: dict[str, re.Match[str]] = {}
    for marker, body in _blocks():
        if marker is None:
            continue
        m = MODEL.fullmatch(marker) or STUDY.fullmatch(marker)
        assert m is not None, f"unreadable example marker {marker!r}"
        (tmp_path / m["file"]).write_text(body, encoding="utf-8")
        (models if marker.startswith("model") else studies)[m["file"]] = m
    return models, studies


def test_every_yaml_block_of_the_format_reference_parses() -> None:
    blocks = _blocks()
    assert len(blocks) >= 12  # 3 complete examples, an invalid one, 8 fragments of the sections
    for k, (_, body) in enumerate(blocks):
        loads_yaml(body, file=f"docs/format.md block {k}")  # YAML 1.2 as crashstudy reads it; raises if not


def test_format_reference_models_validate_with_the_stated_counts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    models, _ = _examples(tmp_path)
    assert set(models) == {"frontal-4mass.yaml", "seat-drop-2d.yaml"}
    for file, m in models.items():
        path = tmp_path / file
        assert main(["validate", str(path)]) == 0, capsys.readouterr()
        model = load_model(str(path)).model
        assert len(model.nodes) == int(m["nodes"])
        assert len(model.springs) == int(m["springs"])
    text = DOC.read_text(encoding="utf-8")
    assert "Five nodes (the barrier is fixed" in text and "Three nodes, three springs" in text


def test_format_reference_study_validates_with_the_stated_variant_count(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, studies = _examples(tmp_path)
    assert set(studies) == {"frontal-doe.yaml"}
    path = tmp_path / "frontal-doe.yaml"
    assert main(["validate", str(path)]) == 0, capsys.readouterr()
    plan = load_study(path)
    stated_count = int(studies["frontal-doe.yaml"]["variants"])
    assert plan.n_variants == stated_count == 3 * 3 * 2  # matrix 3 x 3, crossed with a zip group of 2
    # the numbering the page spells out: matrix axes first (first slowest), then the zip group
    values = plan.axis_values(0, plan.n_variants)
    stated = {0: (11.1, 0.8, 900.0), 1: (11.1, 0.8, 1300.0), 2: (11.1, 1.0, 900.0), 17: (15.6, 1.2, 1300.0)}
    for v, (speed, scale, body) in stated.items():
        got = [
            values[axis][v] for axis in ("impact_velocity", "curves.rail-loading.scale", "nodes.body.mass")
        ]
        assert got == [speed, scale, body]


def test_format_reference_frontal_model_runs_to_the_quoted_numbers(tmp_path: Path) -> None:
    """The page quotes 29 g (body), 33 g (occupant), 0.53 m and 0.24 m of crush (rounded as printed).

    Independent check: with no loads, gravity or walls, the initial kinetic energy
    1/2 (20 + 200 + 1100 + 75) kg (15.6 m/s)^2 = 169,743 J ends as kinetic energy plus the work done
    on the springs, to 1e-6 (the energy balance of the central difference scheme is exact to round-off
    for this model's piecewise-linear laws, up to the trapezoidal damper work)."""
    import crashstudy

    _examples(tmp_path)
    res = crashstudy.simulate(str(tmp_path / "frontal-4mass.yaml"), out_dir=str(tmp_path / "out"))
    row = res.summary.iloc[0]
    assert row["status"] == "ok"
    assert round(row["peak_deceleration_g.body"]) == 29
    assert round(row["peak_deceleration_g.occupant"]) == 33
    assert round(row["max_crush.bumper"], 2) == 0.53
    assert round(row["max_crush.rails"], 2) == 0.24
    ke0 = 0.5 * (20.0 + 200.0 + 1100.0 + 75.0) * 15.6**2
    springs = [c for c in res.summary.columns if c.startswith("absorbed_energy.")]
    assert len(springs) == 6
    total = row["final_kinetic_energy"] + sum(row[c] for c in springs)
    assert total == pytest.approx(ke0, rel=1e-6)
    res.close()


def test_format_reference_links_point_at_files_and_headings_that_exist() -> None:
    text = DOC.read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)\s]+)\)", text)
    assert len(links) >= 15
    for link in links:
        file, _, anchor = link.partition("#")
        target = DOC if not file else (DOC.parent / file)
        assert target.is_file(), link
        if anchor:
            slugs = {_slug(h) for h in re.findall(r"^#+ (.*)$", target.read_text(encoding="utf-8"), re.M)}
            assert anchor in slugs, link


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to '-'."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_readme_guides_table_lists_the_format_reference() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "| [docs/format.md](docs/format.md) |" in readme


OUTSIDE = ("../" + "shared", "SPEC" + ".md")  # spelt in two parts so that this file does not match itself


def test_repository_points_nowhere_outside_itself() -> None:
    """No tracked file refers to the shared folder beside the checkout or its contract file: a clone has neither."""
    listing = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True)
    if listing.returncode != 0:
        pytest.skip("not a git checkout")
    tracked = listing.stdout.split()
    assert len(tracked) > 50
    offenders = []
    for name in tracked:
        path = ROOT / name
        if not path.is_file() or path.suffix in (".png", ".nc", ".parquet"):
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        offenders += [f"{name}: {needle}" for needle in OUTSIDE if needle in text]
    assert offenders == []
