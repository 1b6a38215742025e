"""Faults: YAML attacks through the command line (issue 5, item 4): hostile study and model files (alias
bombs, huge values, variant bombs) are refused with exit 2 and a message naming the line and field,
without a traceback and without hanging.

The contract under test (docs/studies.md, issue 5) and the shared fault study are described in
fault_runs.py."""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Any

import pytest

from fault_runs import FAULT_MODEL, assert_clean_message
from helpers import run_cli as cli  # the command line in this process (helpers.run_cli)
from helpers import run_cli_in_one_process

# ------------------------------------------------------------------------------------------------
# YAML attacks through the command line
# ------------------------------------------------------------------------------------------------

GOOD_STUDY = "name: attack\nmodel: models/fault-model.yaml\nmatrix:\n  nodes.body.mass: [1.0, 2.0]\n"
LAUGHS = "".join(
    f"{chr(97 + k)}: &{chr(97 + k)} [" + ", ".join(["lol" if k == 0 else f"*{chr(96 + k)}"] * 10) + "]\n"
    for k in range(9)
)  # 10^9 values once expanded


def _model(old: str, new: str) -> str:
    assert old in FAULT_MODEL
    return FAULT_MODEL.replace(old, new, 1)


# (id, which file is attacked, its text, the line and field the message must name)
ATTACKS = [
    (
        "python-object-apply",
        "model",
        _model("end_time: 2.0", "end_time: !!python/object/apply:os.system ['touch PWNED']"),
        12,
        "end_time",
    ),
    ("python-name", "model", _model("mass: 2.0}", "mass: !!python/name:os.system }"), 6, "nodes.body.mass"),
    (
        "python-object-new-in-study",
        "study",
        GOOD_STUDY.replace("[1.0, 2.0]", "[!!python/object/new:subprocess.Popen [['touch', 'PWNED']]]"),
        4,
        "matrix.nodes.body.mass.0",
    ),
    (
        "local-tag",
        "study",
        GOOD_STUDY.replace("[1.0, 2.0]", "!custom [1.0, 2.0]"),
        4,
        "matrix.nodes.body.mass",
    ),
    ("billion-laughs-model", "model", LAUGHS + FAULT_MODEL, 6, ""),
    ("billion-laughs-study", "study", LAUGHS + GOOD_STUDY, 6, ""),
    (
        "deep-flow-nesting",
        "model",
        FAULT_MODEL + "description2: " + "[" * 100_000 + "]" * 100_000 + "\n",
        15,
        "",
    ),
    (
        "deep-block-nesting",
        "study",
        GOOD_STUDY
        + "set:\n"
        + "".join("  " * (k + 1) + f"k{k}:\n" for k in range(200))
        + "  " * 201
        + "v: 1\n",
        69,
        "",
    ),
    (
        "huge-integer",
        "study",
        GOOD_STUDY.replace("[1.0, 2.0]", "[" + "9" * 1_000_000 + "]"),
        4,
        "matrix.nodes.body.mass.0",
    ),
    ("float-overflow-to-inf", "model", _model("mass: 2.0}", "mass: 1.0e400}"), 6, "nodes.body.mass"),
    (
        "nan-in-matrix",
        "study",
        GOOD_STUDY.replace("[1.0, 2.0]", "[1.0, .nan]"),
        4,
        "matrix.nodes.body.mass.1",
    ),
    ("inf-in-set", "study", GOOD_STUDY + "set: {end_time: .inf}\n", 5, "set"),
    (
        "minus-inf-in-model",
        "model",
        _model("stiffness: 2.0e4", "stiffness: -.inf"),
        10,
        "springs.spring.material.stiffness",
    ),
    ("document-over-20-MB", "model", FAULT_MODEL + "# " + "x" * (21 * 2**20) + "\n", None, ""),
]


#: attacks whose regression would hang or fill memory: their commands run in a subprocess with a timeout (the
#: others in this process); all of them in ONE subprocess (:func:`may_hang`), with the variant bomb's run
MAY_HANG = {
    "billion-laughs-model",
    "billion-laughs-study",
    "deep-flow-nesting",
    "deep-block-nesting",
    "huge-integer",
    "document-over-20-MB",
}


def _attack_files(root: Path, kind: str, text: str) -> tuple[Path, list[tuple[str | Path, ...]]]:
    """The attacked file (the model or the study, the other one good) written under ``root``; the commands
    that read it."""
    (root / "models").mkdir(parents=True)
    model = root / "models" / "fault-model.yaml"
    study = root / "study.yaml"
    model.write_text(text if kind == "model" else FAULT_MODEL)
    study.write_text(text if kind == "study" else GOOD_STUDY)
    attacked = _attacked(root, kind)
    commands: list[tuple[str | Path, ...]] = [
        ("validate", attacked),
        ("run", study, "-o", root / "out", "--progress", "off"),
    ]
    if kind == "model":
        commands.append(("simulate", model, "-o", root / "out"))
    return attacked, commands


def _attacked(root: Path, kind: str) -> Path:
    return root / "models" / "fault-model.yaml" if kind == "model" else root / "study.yaml"


def _bomb_study(folder: Path) -> Path:
    """A study of 100 values on each of six axes: 10^12 variants."""
    values = "[" + ", ".join(f"{1.0 + k / 100:.2f}" for k in range(100)) + "]"
    axes = [
        "nodes.body.mass",
        "springs.spring.material.stiffness",
        "impact_velocity",
        "end_time",
        "nodes.body.position.0",
        "initial_velocity.body.0",
    ]
    study = folder / "bomb.yaml"
    study.write_text(
        "name: bomb\nmodel: models/fault-model.yaml\nmatrix:\n" + "".join(f"  {a}: {values}\n" for a in axes)
    )
    return study


@pytest.fixture(scope="module")
def may_hang(
    fault_dir: Path, tmp_path_factory: pytest.TempPathFactory
) -> dict[str, tuple[Path, list[tuple[str | Path, ...]], list[subprocess.CompletedProcess[str]]]]:
    """Every command whose regression would hang or fill memory (the MAY_HANG attacks' and the variant
    bomb's run), one after the other in ONE subprocess that must end within 240 s (a hang fails these tests
    at the timeout, a blow-up ends that process and not the test run) in a folder that holds a folder per
    case: one interpreter start instead of seven. {case id: (its folder, its commands, what each did)}."""
    here = tmp_path_factory.mktemp("may-hang")
    cases: dict[str, tuple[Path, list[tuple[str | Path, ...]]]] = {}
    for case, kind, text, _, _ in ATTACKS:
        if case in MAY_HANG:
            cases[case] = (here / case, _attack_files(here / case, kind, text)[1])
    (here / "bomb").mkdir()
    cases["bomb"] = (
        here / "bomb",
        [("run", _bomb_study(fault_dir), "-o", here / "bomb" / "out", "--progress", "off")],
    )
    done = iter(
        run_cli_in_one_process(*[c for _, cmds in cases.values() for c in cmds], cwd=here, timeout=240)
    )
    return {case: (root, cmds, [next(done) for _ in cmds]) for case, (root, cmds) in cases.items()}


@pytest.mark.parametrize(
    ("kind", "text", "line", "field"), [a[1:] for a in ATTACKS], ids=[a[0] for a in ATTACKS]
)
def test_yaml_attack_is_refused_with_exit_2(
    tmp_path: Path, kind: str, text: str, line: int | None, field: str, request: pytest.FixtureRequest
) -> None:
    case = request.node.callspec.id
    if case in MAY_HANG:  # run in the module's one subprocess with a timeout (its working folder: the parent)
        tmp_path, commands, done = request.getfixturevalue("may_hang")[case]
        attacked = _attacked(tmp_path, kind)
        assert not (tmp_path.parent / "PWNED").exists()
    else:
        attacked, commands = _attack_files(tmp_path, kind, text)
        done = [cli(*argv, cwd=tmp_path) for argv in commands]
    for argv, p in zip(commands, done, strict=True):
        assert p.returncode == 2, (argv, p.stdout, p.stderr[-1500:])
        assert "Traceback" not in p.stderr
        lines = p.stderr.splitlines()
        assert lines[0] == "error: invalid input" and len(lines) < 40, p.stderr[:2000]
        where = f"{attacked}:{line}:" if line is not None else f"{attacked}:"
        head = where + (f" {field}:" if field else "")
        assert any(ln.startswith(head) for ln in lines[1:]), (head, p.stderr[:2000])
    assert not (tmp_path / "PWNED").exists()
    assert not (tmp_path / "out").exists()


def test_variant_bomb_is_refused_without_traceback(fault_dir: Path, may_hang: dict[str, Any]) -> None:
    study = _bomb_study(fault_dir)
    p = cli("run", study, "--dry-run")  # refused up front, naming the count and the limit
    assert p.returncode == 2 and "1,000,000,000,000 variants" in p.stderr, p.stderr
    assert_clean_message(p.stderr)
    folder, _, (p,) = may_hang["bomb"]  # the run itself, in the module's one subprocess with a timeout
    out = folder / "out"
    assert p.returncode in (1, 2), p.stderr[-1500:]
    assert_clean_message(p.stderr)
    assert not out.exists() or not any(out.iterdir())
