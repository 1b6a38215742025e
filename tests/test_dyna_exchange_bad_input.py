"""LS-DYNA keyword decks (SPEC 8c): bad decks exit 2 naming file, line and keyword; unsupported features,
include loops, damaged comments, nodes defined twice, constraint codes and links planted at the output."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml

from crashstudy.exchange.dyna_import import import_deck
from dyna_models import DECKS, MATERIAL_MODELS, MODELS, _deck

# --- bad input: exit 2 naming file, line and keyword ----------------------------------------------------

GOOD = (DECKS / "oscillator-fixed.k").read_text()


@pytest.mark.parametrize(
    "edit, where, words",
    [
        (
            lambda t: t.replace("*END", "*CONTACT_AUTOMATIC_SINGLE_SURFACE\n0\n*END"),
            ":39: *CONTACT_AUTOMATIC_SINGLE_SURFACE",
            "--skip-unsupported",
        ),
        (
            lambda t: t.replace("         1   20000.0", "         1   2OOOO.0"),
            ":35: *MAT_SPRING_ELASTIC",
            "field K",
        ),
        (
            lambda t: t.replace(
                "*SECTION_DISCRETE\n$#   secid       dro        kd        v0        cl        fd\n"
                "         1         0       0.0       0.0       0.0       0.0\n$#     cdl       tdl\n"
                "       0.0       0.0\n",
                "*SECTION_DISCRETE\n         1         0\n",
            ),
            ":29: *SECTION_DISCRETE",
            "second is missing",
        ),
        (
            lambda t: t.replace("0             1.0       0", "0                       0"),
            ":38: *ELEMENT_DISCRETE S",
            "blank S reads as 0",
        ),
        (lambda t: t.replace("*END", "*INCLUDE\nnot-there.k\n*END"), ":40: *INCLUDE", "not-there.k"),
    ],
)
def test_bad_deck_exits_2_naming_file_line_and_keyword(
    edit: Any, where: str, words: str, tmp_path: Path, cli: Any
) -> None:
    deck = tmp_path / "bad.k"
    deck.write_text(edit(GOOD))
    assert edit(GOOD) != GOOD
    r = cli("import", str(deck), "-o", str(tmp_path / "m.yaml"))
    assert r.returncode == 2, r.stderr
    assert f"{deck}{where}" in r.stderr and words in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "m.yaml").exists()


def test_skip_unsupported_lists_and_skips(tmp_path: Path, cli: Any) -> None:
    deck = tmp_path / "extra.k"
    deck.write_text(GOOD.replace("*END", "*CONTROL_ENERGY\n2\n*END"))
    r = cli("import", str(deck), "-o", str(tmp_path / "m.yaml"), "--skip-unsupported")
    assert r.returncode == 0, r.stderr
    assert f"{deck}:39: *CONTROL_ENERGY" in r.stderr
    assert (
        yaml.safe_load((tmp_path / "m.yaml").read_text())["springs"]["s1"]["material"]["stiffness"] == 2.0e4
    )
    r = cli("import", str(deck), "-o", str(tmp_path / "m.yaml"), "--skip-unsupported")
    assert r.returncode == 2 and "--force" in r.stderr  # never overwritten without --force


def test_include_loop_is_an_error(tmp_path: Path) -> None:
    (tmp_path / "a.k").write_text("*KEYWORD\n*INCLUDE\nb.k\n*END\n")
    (tmp_path / "b.k").write_text("*KEYWORD\n*INCLUDE\na.k\n*END\n")
    from crashstudy.errors import InputError

    with pytest.raises(InputError, match="include loop: a.k -> b.k -> a.k"):
        import_deck(str(tmp_path / "a.k"))


def test_feature_without_keyword_is_refused_by_name(tmp_path: Path, cli: Any) -> None:
    m = copy.deepcopy(MATERIAL_MODELS["linear_elastic"])
    m["springs"]["s"]["failure"] = {"tension": 0.05}
    m["rigid_walls"] = [{"id": "w", "point": [0.0, -1.0], "normal": [0.0, 1.0], "stiffness": 1.0e6}]
    (tmp_path / "m.yaml").write_text(yaml.safe_dump(m, sort_keys=False))
    r = cli("export", str(tmp_path / "m.yaml"), "--dyna", str(tmp_path / "m.k"))
    assert r.returncode == 2, r.stderr
    assert "springs.s.failure:" in r.stderr and "rigid_walls.0.stiffness:" in r.stderr
    assert f"{tmp_path / 'm.yaml'}:" in r.stderr and not (tmp_path / "m.k").exists()


def test_damaged_crashstudy_comments_are_ignored_not_a_traceback(tmp_path: Path) -> None:
    deck, _ = _deck(copy.deepcopy(MATERIAL_MODELS["elastoplastic"]), tmp_path)
    text = deck.read_text().replace('"nodes":["a","b"]', '"nodes":[1,2]')
    assert text != deck.read_text()
    deck.write_text(text)
    data, notes = import_deck(str(deck))
    assert (
        "damaged" in notes[0]
        and set(data["nodes"]) == {"n1", "n2"}
        and data["rigid_walls"][0]["nodes"] == ["n2"]
    )


def test_node_defined_twice_is_an_error(tmp_path: Path) -> None:
    from crashstudy.errors import InputError

    deck = tmp_path / "twice.k"
    deck.write_text(GOOD.replace("       2             0.1", "       1             0.1"))
    with pytest.raises(
        InputError, match=r"twice.k:12: \*NODE NID: node 1 is defined twice \(also at line 11"
    ):
        import_deck(str(deck))


def test_node_constraint_codes_hold_like_spcs(tmp_path: Path) -> None:
    """*NODE TC = 7 (all translations held) reads as the fixed node of an SPC card."""
    deck = tmp_path / "tc.k"
    spc = "         1         0         1         1         1         1         1         1\n"
    text = GOOD.replace(spc, "").replace(
        "       1             0.0             0.0             0.0\n",
        "       1             0.0             0.0             0.0       7       7\n",
    )
    assert text.count("\n") == GOOD.count("\n") - 1
    deck.write_text(text)
    assert (
        import_deck(str(deck))[0]["nodes"]
        == import_deck(str(DECKS / "oscillator-fixed.k"))[0]["nodes"]
        == {"n1": {"position": [0.0], "fixed": True}, "n2": {"position": [0.1], "mass": 2.0}}
    )


def test_a_link_planted_at_the_output_is_replaced_never_followed(tmp_path: Path) -> None:
    from crashstudy.cli.main import main

    victim = tmp_path / "victim"
    for argv, out in (
        (["export", str(MODELS[0]), "--dyna"], tmp_path / "m.k"),
        (["import", str(DECKS / "oscillator-fixed.k"), "-o"], tmp_path / "m.yaml"),
    ):
        victim.write_text("precious\n")
        out.symlink_to(victim)
        assert main([*argv, str(out), "--force"]) == 0
        assert victim.read_text() == "precious\n" and not out.is_symlink() and out.stat().st_size > 100
