"""Property-based tests (hypothesis) of the command line on corrupted files, through
:func:`crashstudy.cli.main` in this process, as a user's command would run.

**Random corruptions of valid files never crash ``validate``.** A valid model or study text (generated
or one of the examples in ``studies/``) with 1-3 corruptions (a deleted, duplicated or swapped line,
a number turned into text, NaN, infinity or a huge number, swapped ids, random bytes, truncation, a
broken indent) -> exit 0, 1 or 2 and no exception; on 2 stderr is ``error: invalid input`` followed by
``file[:line]: ...`` problem lines, no traceback.

The number of generated inputs that actually ran is counted (property_inputs.py) and printed at the end of
the module (run with ``-s`` to see it); docs/robustness.md quotes it. How many examples each property
draws: property_inputs.py."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from helpers import STUDIES, dump, run_main
from property_inputs import COUNTS, _report_counts  # noqa: F401 - _report_counts: autouse, prints the counts
from strategies import examples, valid_model

# ------------------------------------------------------------------------------------------------
# 2. corrupted files: validate exits 0, 1 or 2 and never raises
# ------------------------------------------------------------------------------------------------

EXAMPLE_MODELS = sorted((STUDIES / "models").glob("*.yaml"))
EXAMPLE_STUDIES = sorted(STUDIES.glob("*.yaml"))
NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?(?![\w.])")
ID_WORD = re.compile(r"\b[a-z][a-z0-9_]*(?:-[a-z0-9_]+)*\b")
BAD_NUMBERS = [
    ".nan",
    ".inf",
    "-.inf",
    "1e400",
    "-1e400",
    "1.0e308",
    "9" * 40,
    "9" * 5000,
    "0",
    "-0.0",
    "1e-320",
    "0x7f",
    "0o17",
    "'1.0'",
    "1_000",
    "NaN",
    "inf",
    "12abc",
    "~",
    "[]",
    "{}",
    "true",
]


@st.composite
def corrupt(draw: st.DrawFn, text: str) -> bytes:
    """``text`` with 1-3 random corruptions, as bytes (some corruptions are not valid UTF-8)."""
    data = text.encode("utf-8")
    for _ in range(draw(st.integers(1, 3))):
        s = data.decode("utf-8", "surrogateescape")
        lines = s.splitlines(keepends=True) or [""]
        op = draw(
            st.sampled_from(
                [
                    "delete-line",
                    "number-to-text",
                    "bad-number",
                    "duplicate-line",
                    "swap-lines",
                    "swap-ids",
                    "random-bytes",
                    "truncate",
                    "indent",
                    "replace-char",
                ]
            )
        )
        COUNTS[f"corruption:{op}"] += 1
        if op == "delete-line":
            del lines[draw(st.integers(0, len(lines) - 1))]
            s = "".join(lines)
        elif op in ("number-to-text", "bad-number"):
            nums = list(NUMBER.finditer(s))
            if not nums:
                continue
            m = draw(st.sampled_from(nums))
            new = (
                draw(st.sampled_from(["heavy", "x", "one", "1.0.0", "1,5", "12 kg", "'3'"]))
                if op == "number-to-text"
                else draw(st.sampled_from(BAD_NUMBERS))
            )
            s = s[: m.start()] + new + s[m.end() :]
        elif op == "duplicate-line":
            k = draw(st.integers(0, len(lines) - 1))
            lines.insert(k, lines[k])
            s = "".join(lines)
        elif op == "swap-lines":
            i, j = draw(st.integers(0, len(lines) - 1)), draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
            s = "".join(lines)
        elif op == "swap-ids":
            words = sorted({m.group() for m in ID_WORD.finditer(s)})
            if len(words) < 2:
                continue
            a, b = draw(st.sampled_from(words)), draw(st.sampled_from(words))
            s = re.sub(rf"\b{re.escape(a)}\b", "\0", s)
            s = re.sub(rf"\b{re.escape(b)}\b", a, s).replace("\0", b)
        elif op == "random-bytes":
            raw = s.encode("utf-8", "surrogateescape")
            k = draw(st.integers(0, len(raw)))
            raw = raw[:k] + draw(st.binary(min_size=1, max_size=8)) + raw[k:]
            s = raw.decode("utf-8", "surrogateescape")
        elif op == "truncate":
            s = s[: draw(st.integers(0, len(s)))]
        elif op == "indent":
            k = draw(st.integers(0, len(lines) - 1))
            lines[k] = draw(st.sampled_from([" ", "   ", "\t", ""])) + lines[k].lstrip(" ")
            s = "".join(lines)
        else:
            if not s:
                continue
            k = draw(st.integers(0, len(s) - 1))
            s = s[:k] + draw(st.sampled_from(list(":-[]{},&*!#'\"|>%@`"))) + s[k + 1 :]
        data = s.encode("utf-8", "surrogateescape")
    return data


@pytest.fixture(scope="module")
def studies_copy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of ``studies/`` so that corrupted study files find their models."""
    dst = tmp_path_factory.mktemp("studies") / "studies"
    shutil.copytree(STUDIES, dst)
    return dst


def _check_validate(path: Path, model_path: Path | None = None) -> None:
    rc, out, err = run_main("validate", str(path))
    COUNTS["corrupted_files_validated"] += 1
    COUNTS[f"validate_exit_{rc}"] += 1
    assert rc in (0, 1, 2), (rc, out, err)
    assert "Traceback" not in err and "Traceback" not in out
    if rc == 2:
        lines = err.splitlines()
        assert lines[0] == "error: invalid input", err
        files = [str(path)] + ([str(model_path)] if model_path else [])
        assert len(lines) >= 2
        for ln in lines[1:]:
            assert ln.startswith("... and ") or any(ln.startswith(f + ":") for f in files), (ln, err)
        with_line = [ln for ln in lines[1:] if any(re.match(re.escape(f) + r":\d+: ", ln) for f in files)]
        if with_line:
            COUNTS["invalid_with_line_number"] += 1
        else:  # only a problem with the file as a whole has no line (encoding, size, missing model)
            assert any(w in err for w in ("not UTF-8", "too large", "not found", "cannot read")), err
    elif rc == 0:
        assert re.search(r": valid (model|study) \(", out), out


@settings(max_examples=examples(100, 250), deadline=None, suppress_health_check=list(HealthCheck))
@given(st.data())
def test_corrupted_model_text_never_crashes_validate(studies_copy: Path, data: st.DataObject) -> None:
    """Draws 100 corrupted models (250 under ``HYPOTHESIS_PROFILE=explore``, new ones on each run)."""
    source = data.draw(st.sampled_from(["generated"] + [p.name for p in EXAMPLE_MODELS]), label="source")
    text = (
        dump(data.draw(valid_model(), label="model"))
        if source == "generated"
        else (STUDIES / "models" / source).read_text(encoding="utf-8")
    )
    raw = data.draw(corrupt(text), label="corrupted")
    path = studies_copy / "models" / "corrupted-model.yaml"
    path.write_bytes(raw)
    _check_validate(path)


@settings(max_examples=examples(60, 150), deadline=None, suppress_health_check=list(HealthCheck))
@given(st.data())
def test_corrupted_study_text_never_crashes_validate(studies_copy: Path, data: st.DataObject) -> None:
    """Draws 60 corrupted studies (150 under ``HYPOTHESIS_PROFILE=explore``, new ones on each run)."""
    source = data.draw(st.sampled_from([p.name for p in EXAMPLE_STUDIES]), label="source")
    text = (STUDIES / source).read_text(encoding="utf-8")
    raw = data.draw(corrupt(text), label="corrupted")
    path = studies_copy / "corrupted-study.yaml"
    path.write_bytes(raw)
    model = re.search(rb"^model:\s*(\S+)", raw, re.M)
    model_path = (studies_copy / model.group(1).decode("utf-8", "replace")).resolve() if model else None
    _check_validate(path, model_path)
