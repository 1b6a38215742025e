"""Provenance and reuse: content hashes of a run's inputs, per study and per variant.

Every result records the crashstudy version, SHA-256 hashes of the model and study texts, and an
input hash per variant: a BLAKE2b digest of everything that determines that variant's numbers (its
parameter column, the shared topology, the sampling, the code version). Re-running a study into a
folder that holds its earlier results reuses every variant whose input hash is unchanged.
"""

from __future__ import annotations

import hashlib

import numpy as np

from crashstudy import __version__
from crashstudy.study import Plan

HASH_LEN = 32  # hex characters of a variant input hash


def text_hash(text: str) -> str:
    """SHA-256 of a file's text (hex)."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def topology_signature(plan: Plan) -> bytes:
    """Bytes of what every variant shares and what changes its results besides its parameters."""
    t = plan.topology
    h = hashlib.blake2b(digest_size=32)
    for arr in (t.spring_nodes, t.material, t.spring_curves, t.curve_offsets, t.fixed, t.load_node, t.load_curve,
                t.pm_node, t.pm_dir, t.pm_kind, t.pm_curve, t.wall_nodes):  # fmt: skip
        h.update(np.ascontiguousarray(arr).tobytes())
        h.update(b"|")
    meta = (t.dim, t.node_ids, t.spring_ids, t.curve_ids, t.wall_ids, t.units, t.time_step_mode, t.histories,
            t.termination, repr(plan.interval), plan.n_out, __version__)  # fmt: skip
    h.update(repr(meta).encode())
    return h.digest()


def variant_hashes(plan: Plan, P: np.ndarray, signature: bytes | None = None) -> list[str]:
    """Input hash of each variant (column of the parameter matrix ``P``)."""
    sig = signature if signature is not None else topology_signature(plan)
    cols = np.ascontiguousarray(P.T)
    return [hashlib.blake2b(sig + col.tobytes(), digest_size=HASH_LEN // 2).hexdigest() for col in cols]
