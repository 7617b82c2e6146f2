"""Bounds checked before anything runs: safe names, file sizes, sample counts, mesh sizes.

* **Names used in paths** (a scene's ``[scene] name``, a run matrix's ``[matrix] name``)
  match :data:`NAME_PATTERN`: a letter or digit, then up to 63 letters, digits, ``_``,
  ``-`` or ``.`` (no ``/``, no leading dot, no control character), so every file written
  under an output directory stays inside it. **Parameter names** (``mu.NAME``, also
  used in the names of ``rbbench solve``'s output directories) match
  :data:`PARAMETER_PATTERN`: a Python identifier of at most 32 characters.
* **Input files** (scene and matrix TOML) are regular files of at most
  :data:`MAX_INPUT_BYTES`, in UTF-8.
* **Sample counts** (``n_train``, ``n_valid``) are at most :data:`MAX_SAMPLES`.
* **Mesh sizes**: the number of HF dofs a ``[discretization]`` gives is estimated from
  the sizes, before meshing (:func:`estimate_dofs`), and refused above
  :func:`max_hf_dofs` (default :data:`DEFAULT_MAX_HF_DOFS`; the environment variable
  ``RBBENCH_MAX_DOFS`` raises or lowers it).
"""

from __future__ import annotations

import functools
import math
import os
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["DEFAULT_MAX_HF_DOFS", "MAX_INPUT_BYTES", "MAX_LOAD_STEPS", "MAX_SAMPLES",
           "NAME_PATTERN", "PARAMETER_PATTERN", "check_name", "estimate_dofs", "max_hf_dofs",
           "read_input", "read_toml", "toml_literal"]

#: A name that may become a file or directory name.
NAME_PATTERN = r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}"
#: A parameter name (``"mu.NAME"`` references, output directory names).
PARAMETER_PATTERN = r"[A-Za-z_][A-Za-z0-9_]{0,31}"
NAME_RULE = ("a letter or digit, then at most 63 letters, digits, '_', '-' or '.' "
             f"(the pattern {NAME_PATTERN}; no '/', no leading dot)")
PARAMETER_RULE = ("a Python identifier of at most 32 characters "
                  f"(the pattern {PARAMETER_PATTERN})")
#: Largest scene or matrix file read (bytes).
MAX_INPUT_BYTES = 1_000_000
#: Largest training or validation set.
MAX_SAMPLES = 100_000
#: Most load steps of a friction scene (``[load] load_steps``): each step is one nonlinear
#: solve of every snapshot (2,000 steps took 35 s for one solve of a coarse hertz_friction
#: mesh of 10,736 dofs; the shipped scenes use 1 or 2).
MAX_LOAD_STEPS = 100
#: Default bound on the estimated HF dofs (``RBBENCH_MAX_DOFS`` overrides it).
DEFAULT_MAX_HF_DOFS = 1_000_000
#: Rough peak memory of an HF contact solve per dof, for the message only (measured: peak RSS
#: of one scikit-fem + SuperLU solve of hertz_halfdisks, 0.42 GB at 37k dofs, 1.2 GB at 75k:
#: mesh, assembly, factorisation and the condensed contact operator).
BYTES_PER_DOF = 16_000
#: Vertices of the graded half-disk mesher per unit of the size integral (fitted on the
#: meshes of ``plugins/backends/meshes.py``: ratios 4.5 to 6 on fine meshes), and its
#: coarsest mesh (the start of the refinement).
_VERTICES_PER_UNIT = 6.0
_COARSE_VERTICES = 34


def check_name(value: Any, pattern: str = NAME_PATTERN) -> bool:
    """Whether ``value`` is a string matching ``pattern`` entirely."""
    return isinstance(value, str) and re.fullmatch(pattern, value) is not None


def read_input(path: Path, what: str) -> str:
    """The text of a scene or matrix file, or ``ValueError`` naming the file and the cause.

    Parameters
    ----------
    path : Path
        The file.
    what : str
        ``"scene"`` or ``"run matrix"`` (for the message).

    Returns
    -------
    str
        The file's content (UTF-8).

    Raises
    ------
    ValueError
        If ``path`` is not a regular file, is larger than :data:`MAX_INPUT_BYTES`, cannot
        be read, or is not UTF-8.
    """
    if path.is_dir():
        raise ValueError(f"{path}: is a directory; expected a {what} .toml file")
    try:
        size = path.stat().st_size
        if not path.is_file():
            raise ValueError(f"{path}: not a regular file; expected a {what} .toml file")
        if size > MAX_INPUT_BYTES:
            raise ValueError(f"{path}: {size} bytes; a {what} file holds at most "
                             f"{MAX_INPUT_BYTES} bytes")
        raw = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the {what} file ({exc.strerror or exc})") from None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a UTF-8 text file (byte {exc.start}: "
                         f"{raw[exc.start:exc.start + 1]!r}); a {what} file is UTF-8 TOML"
                         ) from None


def read_toml(path: Path, what: str) -> dict[str, Any]:
    """The TOML table of a scene or matrix file (:func:`read_input`), or ``ValueError``
    naming the file: not a regular file, too large, not UTF-8, not TOML, or nested too
    deeply for the parser."""
    text = read_input(path, what)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise ValueError(f"{path}: not valid TOML: nested too deeply") from None


def toml_literal(raw: str, where: str) -> Any:
    """``raw`` read as a TOML literal (``--set KEY=VALUE``), else the string itself;
    ``ValueError`` naming ``where`` if it is nested too deeply to parse."""
    try:
        return tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        return raw
    except RecursionError:
        raise ValueError(f"{where}: the value is nested too deeply") from None


def max_hf_dofs() -> int:
    """The bound on the estimated HF dofs: ``RBBENCH_MAX_DOFS`` if set (a positive
    integer), else :data:`DEFAULT_MAX_HF_DOFS`."""
    raw = os.environ.get("RBBENCH_MAX_DOFS", "")
    try:
        value = int(raw)
    except ValueError:
        return DEFAULT_MAX_HF_DOFS
    return value if value > 0 else DEFAULT_MAX_HF_DOFS


@functools.lru_cache(maxsize=256)
def _size_integral(zone: tuple[float, float], h_contact: float, h_max: float,
                   grading: float) -> float:
    """``int dA / h(x)^2`` over the unit lower half-disk, ``h = min(h_contact + grading d,
    h_max)`` with ``d`` the distance to the arc ``theta in zone`` (the mesher's size
    function): a polar rule, radially graded toward the arc and angularly toward the
    zone's ends."""
    th0, th1 = zone
    small = max(min(h_contact, h_max) * 1e-3, 1e-12)
    s = np.concatenate([[0.0], np.geomspace(small, 1.0, 120)])  # 1 - r
    r = 1.0 - s
    rm, dr = 0.5 * (r[1:] + r[:-1]), r[:-1] - r[1:]
    steps = np.geomspace(small, np.pi, 40)
    th = np.concatenate([np.linspace(-np.pi, 0.0, 60), [th0, th1],
                         *(t + sg * steps for t in (th0, th1) for sg in (-1.0, 1.0))])
    th = np.unique(np.clip(th, -np.pi, 0.0))
    tm, dt = 0.5 * (th[1:] + th[:-1]), np.diff(th)
    R, T = np.meshgrid(rm, tm, indexing="ij")
    ang = np.clip(T, th0, th1)
    d = np.hypot(R * np.cos(T) - np.cos(ang), R * np.sin(T) - np.sin(ang))
    h = np.minimum(h_contact + grading * d, h_max)
    return float(np.sum(R / h**2 * dr[:, None] * dt[None, :]))


def estimate_dofs(data: dict[str, Any]) -> int:
    """The HF dof count a validated scene's ``[discretization]`` gives, from its sizes.

    ``unit_square``: exact, ``(degree n + 1)^2`` with ``n = n_cells 2**level``.
    ``halfdisks``: per body, the vertices of the graded mesh estimated as
    ``34 + 6 int dA / h^2`` (``h`` the mesher's size function at ``2**-level`` times the
    scene's sizes; within a factor 1.5 of ``plugins/backends/meshes.py``), times 4 for
    degree 2 (vertices + edge midpoints), times 2 displacement components.

    Parameters
    ----------
    data : dict
        Validated scene data (defaults filled in).

    Returns
    -------
    int
        The estimated number of HF dofs (at least 1).
    """
    disc, geo = data["discretization"], data["geometry"]
    degree, level = int(disc["degree"]), int(disc["level"])
    if geo["kind"] == "unit_square":
        n = int(disc["n_cells"]) * 2**level
        return (degree * n + 1) ** 2
    scale = 2.0 ** (-level)
    h_c, h_m = float(disc["h_contact"]) * scale, float(disc["h_max"]) * scale
    if geo["kind"] == "hemispheres":
        per_body = 3 * (8 if degree == 2 else 1) * _hemisphere_vertices(
            float(geo["contact_cap"]), h_c, h_m)
        return max(1, int(math.ceil(per_body * (1 if geo["lower"] == "rigid_flat" else 2))))
    zones = [tuple(float(x) for x in math.pi * np.asarray(geo["contact_zone"]))]
    if geo.get("lower") == "half_disk":
        mz = math.pi * np.asarray(geo["master_zone"])
        zones.append((-float(mz[1]), -float(mz[0])))
    per_node = 2 * (4 if degree == 2 else 1)
    vertices = sum(_COARSE_VERTICES + _VERTICES_PER_UNIT
                   * _size_integral(z, h_c, h_m, float(disc["grading"])) for z in zones)
    return max(1, int(math.ceil(per_node * vertices)))


def _hemisphere_vertices(cap: float, h_contact: float, h_max: float) -> float:
    """Vertices of the graded unit quarter hemisphere
    (``plugins/backends/hemisphere_mesh.py``): ``200 + V_near / h_contact^3 + 4 V_far /
    h_max^3``, ``V_near`` the quarter half-ball within the cap's chord of the pole;
    within a factor 1.2 of Netgen's count at levels 0 to 2 of ``hertz_sphere``."""
    chord = 2.0 * math.sin(0.5 * math.pi * cap)
    v_near = min(math.pi / 6.0, math.pi * chord**3 / 6.0)
    return 200.0 + v_near / h_contact**3 + 4.0 * (math.pi / 6.0 - v_near) / h_max**3


def check_size(data: dict[str, Any]) -> str | None:
    """``None`` if the estimated dofs are within :func:`max_hf_dofs`, else the reason
    (the estimate, the memory it needs, the bound and how to change it)."""
    dofs, bound = estimate_dofs(data), max_hf_dofs()
    if dofs <= bound:
        return None
    disc = data["discretization"]
    keys = (("level", "n_cells", "degree") if data["geometry"]["kind"] == "unit_square"
            else ("level", "h_contact", "h_max", "grading", "degree"))
    sizes = ", ".join(f"{k} = {disc[k]!r}" for k in keys)
    return (f"{sizes} give about {dofs:.3g} HF dofs (about {dofs * BYTES_PER_DOF / 1e9:.3g} GB "
            f"to solve), more than the bound of {bound} dofs; use coarser sizes (a lower "
            "level, larger h_contact / h_max, fewer n_cells) or raise the bound with the "
            "environment variable RBBENCH_MAX_DOFS")
