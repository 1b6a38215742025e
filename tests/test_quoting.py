"""Error messages quote only what identifies the problem: never a foreign file's contents, never a
terminal control sequence (issue 14 item 3)."""

from __future__ import annotations

from pathlib import Path

import yaml

from helpers import run_cli

SECRET = "s3cr3t-token-do-not-print"


def _study_of(tmp: Path, model: Path) -> Path:
    study = tmp / "study.yaml"
    study.write_text(
        yaml.safe_dump({"name": "probe", "model": str(model), "matrix": {"nodes.b.mass": [1.0]}})
    )
    return study


def test_study_pointing_at_a_system_like_file_does_not_quote_it(tmp_path: Path) -> None:
    passwd = tmp_path / "passwd"  # like /etc/passwd: colon-separated fields, no spaces
    passwd.write_text(
        f"root:x:0:0:{SECRET}:/root:/bin/bash\ndaemon:x:1:1:daemon:/usr/sbin:/usr/sbin/nologin\n"
    )
    for args in (("validate", str(passwd)), ("run", str(_study_of(tmp_path, passwd)))):
        done = run_cli(*args)
        assert done.returncode == 2 and "Traceback" not in done.stderr
        assert SECRET not in done.stderr and "root:x" not in done.stderr
        assert "expected a mapping at top level" in done.stderr and str(passwd) in done.stderr


def test_file_of_key_value_lines_is_refused_without_echoing_its_keys(tmp_path: Path) -> None:
    conf = tmp_path / "service.conf"
    keys = [f"{SECRET}-{k}" for k in range(30)]
    conf.write_text("".join(f"{k}: value-{i}\n" for i, k in enumerate(keys)))
    for args in (("validate", str(conf)), ("run", str(_study_of(tmp_path, conf))), ("simulate", str(conf))):
        done = run_cli(*args)
        assert done.returncode == 2 and "Traceback" not in done.stderr
        assert SECRET not in done.stderr and "value-" not in done.stderr
        assert "not a crashstudy model or study file" in done.stderr and "30 top-level keys" in done.stderr
        assert len(done.stderr.strip().splitlines()) == 2  # "error: invalid input" and one problem


def test_escape_sequences_in_a_key_are_shown_escaped_never_sent_to_the_terminal(tmp_path: Path) -> None:
    model = tmp_path / "model.yaml"
    model.write_text(
        'name: esc\nnodes:\n  a: {position: [0.0], fixed: true}\n  "b\\e[2J\\e]0;pwned\\a": {position: [1.0], mass: 1.0}\n'
        '  "line\\nbreak": {position: [2.0], mass: 1.0}\n'
        "springs:\n  s: {nodes: [a, c], material: {type: linear_elastic, stiffness: 1.0}}\nend_time: 0.1\n"
    )
    done = run_cli("validate", str(model))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "\x1b" not in done.stderr and "\x07" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert all(line.startswith((str(model), "error:")) for line in lines)  # no message split by a newline
    assert "unknown node 'c'" in done.stderr
