"""The SPEC v2 spring features of the twin models (tests/twin_models.py): springs that break, preloaded and
rate-dependent springs, and the rate_elastic model, in 1-D and 2-D."""

from __future__ import annotations

from typing import Any


def _v2_springs(dim: int) -> dict[str, Any]:
    """The SPEC v2 spring features together: elastoplastic (preloaded, breaking in tension), a blow-off
    nonlinear_damper, a preloaded general_nonlinear that yielded on the way, a preloaded crush, a linear
    spring breaking both ways."""
    ax = [1.0] if dim == 1 else [0.6, 0.8]
    at = lambda r: [r * c for c in ax]  # noqa: E731
    return {
        "name": f"v2-springs-{dim}d",
        "curves": {
            "blow-off": {"x": [-10.0, -1.0, 0.0, 1.0, 10.0], "y": [-300.0, -300.0, 0.0, 300.0, 300.0]},
            "load": {"x": [-0.1, 0.0, 0.01, 0.02, 0.2], "y": [-1.0e4, 0.0, 600.0, 400.0, 900.0]},
            "unload": {"x": [-0.1, 0.0, 0.1], "y": [-1.0e4, 0.0, 1.0e4]},
            "crush": {"x": [-0.3, -0.01, 0.0], "y": [-3000.0, -1500.0, 0.0]},
        },
        "nodes": {
            "a": {"position": at(0.0), "fixed": True},
            "b": {"position": at(1.0), "mass": 10.0},
            "c": {"position": at(2.0), "mass": 5.0},
        },
        "springs": {
            "ep": {
                "nodes": ["a", "b"],
                "initial_elongation": 0.02,
                "failure": {"tension": 0.12},
                "material": {
                    "type": "elastoplastic",
                    "stiffness": 4.0e4,
                    "tangent_stiffness": 1.0e4,
                    "yield_force": 2.0e3,
                },
            },
            "nd": {"nodes": ["a", "b"], "material": {"type": "nonlinear_damper", "curve": "blow-off"}},
            "gn": {
                "nodes": ["b", "c"],
                "initial_elongation": 0.015,
                "material": {
                    "type": "general_nonlinear",
                    "loading": "load",
                    "unloading": "unload",
                    "tension_yield": 500.0,
                },
            },
            "cr": {
                "nodes": ["b", "c"],
                "initial_elongation": -0.01,
                "failure": {"compression": -0.2},
                "material": {"type": "crush", "loading": "crush", "unloading_stiffness": 2.0e5},
            },
            "lin": {
                "nodes": ["a", "c"],
                "failure": {"tension": 0.06, "compression": -0.06},
                "material": {"type": "linear_elastic", "stiffness": 2.0e3},
            },
        },
        "initial_velocity": {"b": at(3.0), "c": at(-2.0)},
        "end_time": 0.3,
        "time_step": {"safety_factor": 0.5},
        "output": {"interval": 1.0e-3},
    }


def _v2_intact(dim: int) -> dict[str, Any]:
    """:func:`_v2_springs` without failures and without its general_nonlinear spring (never breaking, it is
    the same code as :func:`_v2_springs`' one): springs that cannot break beside ones that can."""
    model = _v2_springs(dim)
    model["springs"].pop("gn")
    for sp in model["springs"].values():
        sp.pop("failure", None)
    return model


def rate_elastic_model(dim: int) -> dict[str, Any]:
    """rate_elastic: three curves (rates 0, 2, 6 m/s) on a preloaded spring, one curve on another, beside a
    linear spring; the impact speeds put the elongation rates below, between and above the rates, and a
    curve scale axis makes one of its curves a per-variant factor curve."""
    ax = [1.0] if dim == 1 else [0.6, 0.8]
    at = lambda r: [r * c for c in ax]  # noqa: E731
    return {
        "name": f"rate-elastic-{dim}d",
        "curves": {
            "soft": {"x": [-0.2, -0.05, 0.0, 0.05, 0.2], "y": [-800.0, -500.0, 0.0, 500.0, 800.0]},
            "mid": {"x": [-0.2, -0.05, 0.0, 0.05, 0.2], "y": [-1600.0, -1000.0, 0.0, 1000.0, 1600.0]},
            "stiff": {"x": [-0.2, 0.0, 0.1, 0.2], "y": [-4000.0, 0.0, 1500.0, 2500.0]},
        },
        "nodes": {
            "a": {"position": at(0.0), "fixed": True},
            "b": {"position": at(1.0), "mass": 10.0},
            "c": {"position": at(2.0), "mass": 5.0},
        },
        "springs": {
            "re": {
                "nodes": ["a", "b"],
                "initial_elongation": 0.01,
                "material": {
                    "type": "rate_elastic",
                    "curves": [
                        {"rate": 0.0, "curve": "soft"},
                        {"rate": 2.0, "curve": "mid"},
                        {"rate": 6.0, "curve": "stiff"},
                    ],
                },
            },
            "re1": {
                "nodes": ["b", "c"],
                "material": {"type": "rate_elastic", "curves": [{"rate": 1.0, "curve": "mid"}]},
            },
            "lin": {"nodes": ["a", "c"], "material": {"type": "linear_elastic", "stiffness": 2.0e3}},
        },
        "initial_velocity": {"b": at(3.0), "c": at(-2.0)},
        "end_time": 0.3,
        "time_step": {"safety_factor": 0.5},
        "output": {"interval": 1.0e-3},
    }
