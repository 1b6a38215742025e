"""ISO-MME reading and writing against pyisomme, the independent implementation (tests/fixtures/isomme).

pyisomme (1.1.0, an isolated venv: it pins numpy 1.26) wrote the test PYISO-1 and read it back in six
variants (UTF-8, UTF-8 with BOM, cp1252, ISO-8859-1, CRLF, zip); ``pyisomme_read.json`` holds what it read.
It also read the files crashstudy's writer produced (``ours/``): ``pyisomme_read_ours.json``. Tolerances:
pyisomme and crashstudy parse the same decimal text, so values agree to 1e-12 relative (float parsing is
exact; the margin only covers unit factors like 9.80665 applied in a different order).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from crashstudy.exchange.isomme import IsoMmeError, OutChannel, mme_files, read_test
from crashstudy.exchange.testcurve import read_curve

FIX = Path(__file__).resolve().parent / "fixtures" / "isomme"
PY = json.loads((FIX / "pyisomme_read.json").read_text(encoding="utf-8"))
VARIANTS = {
    "utf8": FIX / "pyisomme/utf8/PYISO-1",
    "utf8bom": FIX / "pyisomme/utf8bom/PYISO-1/PYISO-1.mme",
    "cp1252": FIX / "pyisomme/cp1252/PYISO-1",
    "latin1": FIX / "pyisomme/latin1/PYISO-1",
    "crlf": FIX / "pyisomme/crlf/PYISO-1",
    "zip": FIX / "pyisomme/zip/PYISO-1.zip",
}
RTOL = 1e-12


def _values(rec: dict) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in rec["value"]], dtype=float)


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_reads_what_pyisomme_read(variant: str) -> None:
    """Every channel of every encoding variant: code, unit, sample count, times and values (NOVALUE as
    NaN, explicit time from the TIRS channel) equal to what pyisomme read from the same bytes."""
    assert PY["variants"][variant]["same_as_utf8"]
    test = read_test(VARIANTS[variant])
    assert (
        test.header["Laboratory name"] == PY["variants"][variant]["laboratory"] == "Prüfstand Köln (Ü-Halle)"
    )
    assert sorted(test.codes.values()) == sorted(PY["utf8"]["channels"])
    for code, rec in PY["utf8"]["channels"].items():
        ch = test.find(code)
        assert ch.unit == rec["unit"] and ch.name == rec["name"]
        y = _values(rec)
        assert len(ch.values) == rec["n"] == len(y)
        np.testing.assert_array_equal(np.isnan(ch.values), np.isnan(y))
        np.testing.assert_allclose(ch.values, y, rtol=RTOL, equal_nan=True)
        if code[2:6] != "TIRS":  # pyisomme gives a time reference channel a sample index
            np.testing.assert_allclose(test.times(ch), rec["time"], rtol=RTOL, atol=1e-15)


def test_novalue_and_explicit_time_present() -> None:
    """The fixture holds what it must: NOVALUE samples and an explicit-time channel (so the test above
    can fail on them)."""
    rec = PY["utf8"]["channels"]
    assert sum(v is None for v in rec["11HEAD0000H3ACXA"]["value"]) == 3
    belt = read_test(VARIANTS["utf8"]).find("10SEBE0000B3FO00")
    assert belt.header["Reference channel"] == "explicit"
    assert np.any(np.abs(np.diff(np.diff(rec["10SEBE0000B3FO00"]["time"]))) > 1e-6)  # uneven: not implicit
    raw = (FIX / "pyisomme/cp1252/PYISO-1/PYISO-1.mme").read_bytes()
    assert "Prüfstand".encode("cp1252") in raw and b"\xc3" not in raw
    assert b"\r\n" in (FIX / "pyisomme/crlf/PYISO-1/PYISO-1.mme").read_bytes()
    assert (FIX / "pyisomme/utf8bom/PYISO-1/PYISO-1.mme").read_bytes().startswith(b"\xef\xbb\xbf")


@pytest.mark.parametrize(
    ("code", "quantity", "system", "factor", "tfactor"),
    [
        ("11HEAD0000H3ACXA", "acceleration", "SI", 9.80665, 1.0),  # g -> m/s^2
        ("11HEAD0000H3ACXA", "acceleration", "mm-ms-kg-kN", 9.80665e-3, 1e3),  # g -> mm/ms^2, s -> ms
        ("10VEHCCG0000ACX0", "acceleration", "mm-s-t-N", 1e3, 1.0),  # m / s2 -> mm/s^2
        ("10VEHCCG0000VEX0", "velocity", "SI", 1 / 3.6, 1.0),  # km/h -> m/s
        ("11CHST0000H3VEX0", "velocity", "mm-ms-kg-kN", 1.0, 1e3),  # m/s = mm/ms
        ("10VEHCCG0000DSX0", "displacement", "SI", 1e-3, 1.0),  # mm -> m
        ("11FEMRLE00H3FOZB", "spring_force", "SI", 1e3, 1.0),  # kN -> N
        ("10SEBE0000B3FO00", "spring_force", "mm-ms-kg-kN", 1.0, 1e3),  # kN = kN, explicit time
    ],
)
def test_units_converted_into_the_model(
    code: str, quantity: str, system: str, factor: float, tfactor: float
) -> None:
    """Hand-derived unit factors (closed form) on pyisomme's numbers."""
    rec = PY["utf8"]["channels"][code]
    c = read_curve(VARIANTS["zip"], channel=code, quantity=quantity, system=system)
    np.testing.assert_allclose(c.value, _values(rec) * factor, rtol=RTOL, equal_nan=True)
    np.testing.assert_allclose(c.time, np.array(rec["time"]) * tfactor, rtol=RTOL, atol=1e-15)


def test_wildcards_and_ambiguity() -> None:
    path = VARIANTS["cp1252"]
    assert read_curve(path, channel="11HEAD??????ACX?", quantity="acceleration").label.endswith(
        "11HEAD0000H3ACXA"
    )
    with pytest.raises(IsoMmeError) as e:
        read_curve(path, channel="10VEHCCG0000????", quantity="acceleration")
    assert e.value.field == "channel" and "3 channels match" in str(e.value)
    for code in ("10VEHCCG0000ACX0", "10VEHCCG0000VEX0", "10VEHCCG0000DSX0"):
        assert code in str(e.value)
    with pytest.raises(IsoMmeError, match="no channel matches") as e:
        read_curve(path, channel="99XXXX0000000000", quantity="acceleration")
    with pytest.raises(IsoMmeError, match="16-character") as e:
        read_curve(path, channel="11HEAD*", quantity="acceleration")


def test_unit_errors_and_override() -> None:
    path = VARIANTS["utf8"]
    with pytest.raises(
        IsoMmeError, match="is a unit of velocity; the model's acceleration needs a unit of acceleration"
    ) as e:
        read_curve(path, channel="10VEHCCG0000VEX0", quantity="acceleration")
    assert e.value.field == "unit"
    with pytest.raises(IsoMmeError, match="unknown unit 'furlong'"):
        read_curve(path, channel="10VEHCCG0000DSX0", unit="furlong", quantity="displacement")
    # unit: overrides the file's: the mm channel declared in m gives 1000x the values
    a = read_curve(path, channel="10VEHCCG0000DSX0", quantity="displacement")
    b = read_curve(path, channel="10VEHCCG0000DSX0", unit="m", quantity="displacement")
    np.testing.assert_allclose(b.value, a.value * 1e3, rtol=RTOL)


def test_bad_files_name_file_and_line(tmp_path: Path) -> None:
    src = VARIANTS["utf8"]
    dst = tmp_path / "T"
    (dst / "Channel").mkdir(parents=True)
    for p in src.rglob("*"):
        if p.is_file():
            (dst / p.relative_to(src)).write_bytes(p.read_bytes())
    f = dst / "Channel" / "PYISO-1.002"
    lines = f.read_text(encoding="utf-8").splitlines()
    lines[20] = "1.5e"
    f.write_text("\n".join(lines), encoding="utf-8")
    with pytest.raises(IsoMmeError, match=r"PYISO-1\.002, line 21: expected a number or NOVALUE"):
        read_curve(dst, channel="10VEHCCG0000ACX0", quantity="acceleration")
    f.write_text("\n".join(lines[:-3]).replace("1.5e", "1.5"), encoding="utf-8")
    with pytest.raises(IsoMmeError, match="'Number of samples' is 120, the file has 117 values"):
        read_curve(dst, channel="10VEHCCG0000ACX0", quantity="acceleration")


# --- writing ------------------------------------------------------------------------------------------


def ours_channels() -> list[OutChannel]:
    """The channels of the writer fixture (``ours/``): deterministic, with a NaN, in every SI unit written."""
    t = np.arange(50) * 2e-4
    acc = 200.0 * np.sin(np.pi * t / 0.01)
    acc[7] = np.nan
    return [
        OutChannel("10VEHCCG0000ACX0", "cabin (acceleration x)", "m/(s*s)", 0.0, 2e-4, acc),
        OutChannel(
            "10VEHCCG0000ACXD",
            "cabin (acceleration x, CFC 60)",
            "m/(s*s)",
            0.0,
            2e-4,
            acc * 0.9,
            (("Channel frequency class", "60"),),
        ),
        OutChannel("10VEHCCG0000VEX0", "cabin (velocity x)", "m/s", 0.0, 2e-4, 15.0 - np.cumsum(acc) * 1e-4),
        OutChannel("10VEHCCG0000DSX0", "cabin (displacement x)", "m", 0.0, 2e-4, t * 15.0 - t**2),
        OutChannel(
            "10SPRGCRASH00FO0", "crash-box (spring force)", "N", 0.0, 2e-4, -1.5e5 * np.sin(t * 300.0)
        ),
    ]


def test_writer_fixture_is_current(tmp_path: Path) -> None:
    """``ours/`` (what pyisomme read into pyisomme_read_ours.json) is byte for byte what the writer writes
    now: a writer change fails here until the fixtures are regenerated (README.md)."""
    files = mme_files("crashstudy-7", [("Title", "crashstudy ours fixture")], ours_channels())
    for rel, data in files.items():
        assert (FIX / "ours" / "crashstudy-7" / rel).read_bytes() == data, rel
    assert len(list((FIX / "ours" / "crashstudy-7").rglob("*.*"))) == len(files)


def test_pyisomme_read_our_files() -> None:
    """pyisomme read crashstudy's files to the written numbers: code, unit, t0, dt, count and values."""
    got = json.loads((FIX / "pyisomme_read_ours.json").read_text())["tests"]["crashstudy-7"]["channels"]
    chans = ours_channels()
    assert sorted(got) == sorted(c.code for c in chans)
    for c in chans:
        rec = got[c.code]
        assert rec["unit"] == c.unit and rec["name"] == c.name
        assert (rec["t0"], rec["dt"], rec["n"]) == (c.t0, c.dt, len(c.values))
        np.testing.assert_allclose(_values(rec), c.values, rtol=1e-11, equal_nan=True)  # 12 digits written
        np.testing.assert_allclose(
            rec["time"], c.t0 + c.dt * np.arange(len(c.values)), rtol=1e-12, atol=1e-15
        )
        ours = read_test(FIX / "ours" / "crashstudy-7").find(c.code)
        np.testing.assert_allclose(ours.values, _values(rec), rtol=RTOL, equal_nan=True)
