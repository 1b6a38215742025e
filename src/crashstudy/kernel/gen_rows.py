"""The rows of a generated kernel's block work array ``Z``, by name: every per-lane number the generated
step keeps between steps is one row (``Z[row * ROW + w]`` for lane ``w``).

A row is named by its family and its indices, ``R["x", n, d]`` (node n's position along d), ``R["pf", s]``
(spring s's peak force), ``R["dt"]``; the families are typed below by how many indices they take, so mypy
rejects an unknown family or a wrong count. :func:`crashstudy.kernel.gen_shape.layout` hands the rows out in
a fixed order (the row numbers, and so the generated source, depend on that order only).
"""

from __future__ import annotations

from typing import Literal, TypeAlias, overload

# one row per lane
Scalar: TypeAlias = Literal[
    "dt",  # the lane's time step
    "lim",  # its last step (-1.0: failed)
    "thr",  # the energy-balance threshold of the instability test
    "ke0",
    "err",
    "ken",
    "ien",
    "efl",  # KE at t = 0, peak energy error, KE and IE at t^n, energy floor
    "kef",
    "tmin",
    "stop",  # early termination: KE fraction, minimum time, stopped
    "ein",
    "esc",  # preloaded springs: energy at t = 0, energy scale
    "work",
    "wmax",  # external work and its peak |.|
    "nst",  # prescribed motion: the lane's last step
    "crushed",  # 2-D: the first collapsed spring (-1.0: none)
    "wall_e",  # energy stored in the walls
]
# one row per node n, spring s, wall wl, dimension d, load or prescribed motion k, curve c or knot k
One: TypeAlias = Literal[
    "m",
    "pa",  # node: mass, peak |a|^2
    "kp",
    "fp",
    "ep",
    "ie",
    "pf",
    "mc",
    "me",
    "sg",
    "l0",  # spring: parameter, F and e of the previous step,
    # absorbed energy, peak force, largest crush and elongation, 1-D axis sign, 2-D length at rest
    "kh",
    "kth",  # spring with knots: crossed this step, crossing fraction
    "kt",
    "fy",  # elastoplastic: tangent stiffness, yield force
    "e0",
    "r0",  # preloaded: initial elongation, its rate at t = 0
    "ft",
    "fc",
    "br",  # breakable: failure elongations in tension and compression, broken
    "yt",
    "yc",
    "F",
    "E",
    "rev",
    "ed",  # general_nonlinear: yields, F and e of pass A, reversal, edot
    "gkc",
    "gkx",
    "gky",
    "gksh",  # general_nonlinear with knots: the knot search
    "pw",
    "wi",
    "wk",
    "wf",  # wall: peak force, impulse, stiffness, force
    "g",  # gravity along d
    "pms",
    "pma",  # prescribed motion k: scale, acceleration
    "cfy",
    "cfx",
    "cff",  # factor curve c: force, abscissa and slope factors
    "cy0",
    "s0",  # curve c: first ordinate and slope
    "cx",
    "ds",
    "kyv",  # knot k: abscissa, slope change, force
]
# node n x dimension d, spring s x d or state row, load k x d, wall wl x d or node
Two: TypeAlias = Literal[
    "x",
    "x0",
    "v",
    "im",
    "a",
    "ao",
    "v0",
    "fx",  # node: x, x0, v, 1/m, a^n, a^{n-1}, v0, external force
    "xs",
    "am",
    "wa",
    "xh",
    "vh",  # static node's x; a^n kept for criteria; at a wall; x and v for histories
    "kdf",
    "ap",
    "ax",
    "axh",  # spring x d: force jump x axis at a knot; previous, pass-A, history axis
    "st",
    "rt",  # spring: material state row k, rate_elastic curve k's rate
    "lf",  # load k along d
    "wn",
    "wp",  # wall wl: normal and point along d
    "pen",  # wall wl x node n: stored penalty energy
]
Three: TypeAlias = Literal["jp"]  # wall wl x node n x d: the velocity jump of the previous step
Key: TypeAlias = Scalar | tuple[One, int] | tuple[Two, int, int] | tuple[Three, int, int, int]
# a curve coefficient (a row, or a register constant: kernel.gen_constants)
CoefName: TypeAlias = Literal["cy0", "s0", "cx", "ds", "kyv"]
Coef: TypeAlias = tuple[CoefName, int]


def coef_name(key: Coef) -> str:
    """A coefficient's name in the generated source (after ``k_``): ``cy0_3``, ``s0_3``, ``cx12``, ``ds12``."""
    name, i = key
    return f"{name}_{i}" if name[-1].isdigit() else f"{name}{i}"


class Rows:
    """Row numbers of the block work array, handed out in order (:meth:`add`) and read as source text
    (``R[key]``: the element of lane ``w``, ``Z[row * stride + w]``)."""

    def __init__(self, stride: int) -> None:
        self.stride = stride
        self.n = 0
        self._at: dict[str | tuple[str | int, ...], int] = {}

    @overload
    def add(self, name: Scalar) -> None: ...
    @overload
    def add(self, name: One, i: int, /) -> None: ...
    @overload
    def add(self, name: Two, i: int, j: int, /) -> None: ...
    @overload
    def add(self, name: Three, i: int, j: int, k: int, /) -> None: ...

    def add(self, name: str, *idx: int) -> None:
        self._add(name, idx)

    def _add(self, name: str, idx: tuple[int, ...]) -> None:
        key: str | tuple[str | int, ...] = (name, *idx) if idx else name
        assert key not in self._at, f"row {key} handed out twice"
        self._at[key] = self.n
        self.n += 1

    @overload
    def each(self, names: tuple[Scalar, ...]) -> None: ...
    @overload
    def each(self, names: tuple[One, ...], i: int, /) -> None: ...
    @overload
    def each(self, names: tuple[Two, ...], i: int, j: int, /) -> None: ...

    def each(self, names: tuple[str, ...], *idx: int) -> None:
        """:meth:`add` of each name in order, with the same indices."""
        for name in names:
            self._add(name, idx)

    def row(self, key: Key) -> int:
        return self._at[key]

    def __contains__(self, key: Key) -> bool:
        return key in self._at

    def __getitem__(self, key: Key) -> str:
        """The work-array element of row ``key`` for lane ``w``, as source text."""
        return f"Z[{self._at[key] * self.stride} + w]"
