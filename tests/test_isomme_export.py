"""``crashstudy export DIR --isomme OUT``, ``iso_mme:`` and ``calibrate.data: {path, channel, unit}``
against closed forms (docs/isomme.md).

The model: a 2 kg body on a 2e4 N/m spring at 1 m/s, written in mm-ms-kg-kN (so every exported channel
goes through a unit conversion): x(t) = v0/w sin(w t), w = sqrt(k/m) = 100 rad/s, spring force k x.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from crashstudy.cli.main import main
from crashstudy.exchange.isomme import OutChannel, mme_files, read_test

K, M, V0 = 2.0e4, 2.0, 1.0
W = np.sqrt(K / M)
MODEL = {
    "name": "lin",
    "units": "mm-ms-kg-kN",
    "nodes": {"anchor": {"position": [0.0], "fixed": True}, "body": {"position": [100.0], "mass": M}},
    "springs": {
        "s": {"nodes": ["anchor", "body"], "material": {"type": "linear_elastic", "stiffness": K * 1e-6}}
    },
    "initial_velocity": {"body": [V0]},
    "end_time": 50.0,
    "metrics": [{"node": "body", "cfc": 60, "criteria": ["peak_g"]}],
    "iso_mme": {"body": "10VEHCCG0000"},
}


def _write(tmp: Path, name: str, data: dict) -> Path:
    path = tmp / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_export_writes_si_channels_with_codes_and_closed_form_values(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Codes (iso_mme prefix, default spring prefix, dimension, direction, filter letter D for CFC 60),
    SI units and SI time, and the values of the closed form within 0.5 % of the amplitude."""
    model = _write(tmp_path, "lin.yaml", MODEL)
    assert main(["simulate", str(model), "-o", str(tmp_path / "res")]) == 0
    out = tmp_path / "iso"
    assert main(["export", str(tmp_path / "res"), "--isomme", str(out)]) == 0
    test = read_test(out / "lin-0")
    assert sorted(test.codes.values()) == [
        "10SPRG000100DS00",
        "10SPRG000100FO00",
        "10VEHCCG0000ACRD",
        "10VEHCCG0000ACX0",
        "10VEHCCG0000DSX0",
        "10VEHCCG0000VEX0",
    ]
    assert test.header["Laboratory test ref. number"] == "lin-0"
    amp = {
        "10VEHCCG0000DSX0": (V0 / W, np.sin, "m"),
        "10VEHCCG0000VEX0": (V0, np.cos, "m/s"),
        "10VEHCCG0000ACX0": (-V0 * W, np.sin, "m/(s*s)"),
        "10SPRG000100FO00": (K * V0 / W, np.sin, "N"),
    }
    for code, (a, f, unit) in amp.items():
        ch = test.find(code)
        t = test.times(ch)
        assert ch.unit == unit and ch.header["Data source"] == "calculated"
        assert t[-1] == pytest.approx(0.05) and t[0] == 0.0  # 50 ms in seconds
        np.testing.assert_allclose(ch.values, a * f(W * t), atol=0.005 * abs(a))
    filt = test.find("10VEHCCG0000ACRD")
    assert filt.name == "body filtered_acceleration CFC 60" and filt.header["Channel frequency class"] == "60"
    assert test.find("10SPRG000100FO00").name == "s spring_force"
    # bad input: exit 2 naming the field, no traceback; an existing test needs --force
    capsys.readouterr()
    assert main(["export", str(tmp_path / "res"), "--isomme", str(out), "--variants", "0-3"]) == 2
    assert "--variants: '0-3': expected variants within 0 .. 0" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "res"), "--isomme", str(out)]) == 2
    assert "lin-0 exist; use --force" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "res"), "--isomme", str(out), "--force"]) == 0
    # plot --test: the exported channel read back into the results' units lies on the model's own line
    from crashstudy import open_results
    from crashstudy.analysis.plot import plot_history
    from crashstudy.exchange.testcurve import read_curve

    ds = open_results(tmp_path / "res").dataset
    curve = read_curve(
        out / "lin-0", channel="10VEHCCG????ACX0", quantity="acceleration", system="mm-ms-kg-kN"
    )
    fig = plot_history(ds, "acceleration", ["body"], test=curve)
    model_line, test_line = fig.axes[0].lines[0], fig.axes[0].lines[-1]
    assert test_line.get_gid() == "test"
    np.testing.assert_allclose(test_line.get_xdata(), model_line.get_xdata(), rtol=1e-11)
    np.testing.assert_allclose(test_line.get_ydata(), model_line.get_ydata(), rtol=1e-10, atol=1e-14)
    assert (
        main(
            [
                "plot",
                str(tmp_path / "res"),
                "--quantity",
                "acceleration",
                "--items",
                "body",
                "--test",
                str(out / "lin-0"),
                "--channel",
                "10VEHCCG0000ACX0",
                "-o",
                str(tmp_path / "png"),
            ]
        )
        == 0
    )
    capsys.readouterr()
    assert (
        main(
            [
                "plot",
                str(tmp_path / "res"),
                "--quantity",
                "acceleration",
                "--items",
                "body",
                "--test",
                str(out / "lin-0"),
                "--channel",
                "10VEHCCG0000????",
                "-o",
                str(tmp_path / "png"),
            ]
        )
        == 2
    )
    assert "--channel: " in capsys.readouterr().err


@pytest.mark.parametrize(
    ("iso", "expected"),
    [
        ({"nobody": "10VEHCCG0000"}, "iso_mme.nobody: unknown id 'nobody'"),
        ({"body": "10VEHCCG00"}, "iso_mme.body"),
        ({"body": "10VEHCCG0000", "s": "10VEHCCG0000"}, "code 10VEHCCG0000 is already 'body'"),
    ],
)
def test_a_bad_iso_mme_map_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], iso: dict, expected: str
) -> None:
    model = _write(tmp_path, "lin.yaml", {**MODEL, "iso_mme": iso})
    capsys.readouterr()
    assert main(["validate", str(model)]) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err, err


def _test_pulse(tmp: Path, k: float) -> Path:
    """An ISO-MME test of the body's acceleration in g (closed form, k), 0.2 ms sampling to 40 ms."""
    t = np.arange(201) * 2e-4
    acc_g = -V0 * np.sqrt(k / M) * np.sin(np.sqrt(k / M) * t) / 9.80665
    files = mme_files(
        "DROP-1",
        [("Title", "synthetic")],
        [
            OutChannel("10VEHCCG0000ACX0", "body", "g", 0.0, 2e-4, acc_g),
            OutChannel("10VEHCCG0000VEX0", "body velocity", "km/h", 0.0, 2e-4, 3.6 * np.cos(t)),
        ],
    )
    for rel, data in files.items():
        (tmp / "DROP-1" / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp / "DROP-1" / rel).write_bytes(data)
    return tmp / "DROP-1"


def test_calibration_from_an_isomme_test_recovers_the_stiffness(tmp_path: Path) -> None:
    """The test's acceleration in g and seconds, the model in mm-ms-kg-kN: k recovered within 0.5 %."""
    k_true = 2.6e4
    _test_pulse(tmp_path, k_true)
    _write(tmp_path, "lin.yaml", {k: v for k, v in MODEL.items() if k != "metrics"})
    study = _write(
        tmp_path,
        "cal.yaml",
        {
            "name": "cal",
            "model": "lin.yaml",
            "calibrate": {
                "data": {"path": "DROP-1", "channel": "10VEHCCG????ACX?"},
                "channel": {"quantity": "acceleration", "node": "body"},
                "variables": {"springs.s.material.stiffness": [0.01, 0.04]},
            },
        },
    )
    out = tmp_path / "out"
    assert main(["calibrate", str(study), "-o", str(out)]) == 0
    cal = yaml.safe_load((out / "calibrated.yaml").read_text())
    assert cal["variables"]["springs.s.material.stiffness"] == pytest.approx(k_true * 1e-6, rel=0.005)


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        ({"path": "DROP-1", "channel": "10VEHCCG0000????"}, "calibrate.data.channel"),
        (
            {"path": "DROP-1", "channel": "10VEHCCG0000????"},
            "DROP-1: channel '10VEHCCG0000????': 2 channels match: 10VEHCCG0000ACX0, 10VEHCCG0000VEX0",
        ),
        ({"path": "DROP-1", "channel": "10VEHCCG0000VEX0"}, "calibrate.data.unit:"),
        ({"path": "DROP-1", "channel": "10VEHCCG0000ACX0", "unit": "furlong"}, "unknown unit 'furlong'"),
        ({"path": "nothere", "channel": "10VEHCCG0000ACX0"}, "calibrate.data.path: data file"),
        ("DROP-1", "calibrate.data: "),
    ],
)
def test_a_bad_data_block_is_exit_2_in_validate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], data: object, expected: str
) -> None:
    _test_pulse(tmp_path, K)
    _write(tmp_path, "lin.yaml", MODEL)
    study = _write(
        tmp_path,
        "cal.yaml",
        {
            "name": "cal",
            "model": "lin.yaml",
            "calibrate": {
                "data": data,
                "channel": {"quantity": "acceleration", "node": "body"},
                "variables": {"springs.s.material.stiffness": [0.01, 0.04]},
            },
        },
    )
    capsys.readouterr()
    assert main(["validate", str(study)]) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err and "cal.yaml:" in err, err
