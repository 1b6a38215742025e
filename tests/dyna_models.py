"""What the LS-DYNA keyword deck tests (tests/test_dyna_exchange_*.py) share: the models exported (the
example models and one 2-D model per material), a model written to a deck, a model dict parsed, a
column of the cards dynars read, and the folder of the decks written by hand (tests/dyna_decks)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from crashstudy.exchange.dyna_export import export_deck
from crashstudy.schema import load_model, parse_model
from crashstudy.schema.yamlio import loads_yaml

MODELS = sorted((Path(__file__).resolve().parents[1] / "studies" / "models").glob("*.yaml"))


def _curve(x: list[float], y: list[float]) -> dict[str, list[float]]:
    return {"x": x, "y": y}


def _two_node(material: dict[str, Any], curves: dict[str, Any] | None = None, **extra: Any) -> dict[str, Any]:
    """A 2-D model: a fixed node and a 2 kg mass on one inclined spring, moving in at 3 m/s."""
    m: dict[str, Any] = {
        "name": f"one-{material['type']}",
        "units": "SI",
        "curves": curves or {},
        "nodes": {"a": {"position": [0.0, 0.0], "fixed": True}, "b": {"position": [0.3, 0.1], "mass": 2.0}},
        "springs": {"s": {"nodes": ["a", "b"], "material": material}},
        "initial_velocity": {"b": [-3.0, -1.0]},
        "end_time": 0.06,
        "output": {"interval": 5.0e-4},
    }
    m.update(extra)
    return m


ELASTIC = _curve([-0.2, -0.05, 0.0, 0.05, 0.2], [-9000.0, -1500.0, 0.0, 1200.0, 7000.0])
MATERIAL_MODELS = {
    "linear_elastic": _two_node(
        {"type": "linear_elastic", "stiffness": 2.0e4},
        loads=[{"node": "b", "force": [10.0, -5.0]}],
        time_step={"safety_factor": 0.5},
    ),
    "damper": _two_node({"type": "damper", "damping": 60.0}, gravity=[0.0, -9.80665]),
    "elastoplastic": _two_node(
        {"type": "elastoplastic", "stiffness": 2.0e4, "tangent_stiffness": 2.0e3, "yield_force": 150.0},
        rigid_walls=[{"id": "floor", "point": [0.0, 0.07], "normal": [0.1, 1.0], "nodes": ["b"]}],
    ),
    "nonlinear_elastic": _two_node(
        {"type": "nonlinear_elastic", "curve": "c"},
        {"c": ELASTIC, "pulse": _curve([0.01, 0.02, 0.03], [0.0, 1.0, 0.5])},
        loads=[{"node": "b", "force": [0.0, -400.0], "curve": "pulse"}],
    ),
    "nonlinear_damper": _two_node(
        {"type": "nonlinear_damper", "curve": "c"},
        {"c": _curve([-5.0, 0.0, 1.0, 5.0], [-900.0, 0.0, 100.0, 300.0])},
    ),
    "general_nonlinear": _two_node(
        {"type": "general_nonlinear", "loading": "l", "unloading": "u", "compression_yield": -1000.0},
        {"l": ELASTIC, "u": _curve([-0.01, 0.0, 0.01], [-800.0, 0.0, 800.0])},
    ),
    "crush": _two_node(
        {"type": "crush", "loading": "c", "unloading_stiffness": 5.0e4},
        {"c": ELASTIC},
        nodes={
            "a": {"position": [0.0, 0.0], "fixed": ["y"], "mass": 50.0},
            "b": {"position": [0.3, 0.1], "mass": 2.0},
        },
        prescribed_motion=[
            {"node": "a", "quantity": "velocity", "direction": "x", "curve": "v", "scale": 2.0}
        ],
    ),
    "rate_elastic": _two_node(
        {"type": "rate_elastic", "curves": [{"rate": 0.0, "curve": "c"}, {"rate": 4.0, "curve": "f"}]},
        {"c": ELASTIC, "f": _curve([-0.1, 0.0, 0.1], [-12000.0, 0.0, 10000.0])},
    ),
}
MATERIAL_MODELS["crush"]["curves"]["v"] = _curve([0.0, 0.02, 0.04], [0.0, 1.0, 1.0])
MATERIAL_MODELS["linear_elastic"]["springs"]["s"]["initial_elongation"] = 0.01


def _deck(model: dict[str, Any] | Path, tmp_path: Path) -> tuple[Path, dict[str, Any]]:
    lm = (
        load_model(str(model))
        if isinstance(model, Path)
        else parse_model(loads_yaml(yaml.safe_dump(model, sort_keys=False), "m.yaml"))
    )
    text, rounded = export_deck(lm.model, lm.doc)
    assert rounded == []
    deck = tmp_path / "model.k"
    deck.write_text(text)
    return deck, dict(lm.doc.data)


def _col(table: dict[str, Any], name: str) -> list[Any]:
    v = table[name]
    return v.tolist() if hasattr(v, "tolist") else list(v)


def load_model_data(data: dict[str, Any]) -> Any:
    return parse_model(loads_yaml(yaml.safe_dump(data, sort_keys=False), "m.yaml")).model


# --- decks written by hand from the manual's layouts, against closed forms ---------------------------

DECKS = Path(__file__).resolve().parent / "dyna_decks"
