"""Argument helpers shared by the commands."""

from __future__ import annotations

from rbbench.runtime import openblas_env as _openblas_env  # noqa: F401  (first: before numpy loads OpenBLAS)
from rbbench.scene.loading import SceneError, tomllib


def _backend_options(items: list[str] | None, flag: str = "--backend-option") -> dict:
    """``FLAG KEY=VALUE`` pairs (``--backend-option``, ``--formulation-option``); a value is
    a TOML literal, else a string."""
    options = {}
    for text in items or ():
        key, sep, raw = text.partition("=")
        key, raw = key.strip(), raw.strip()
        if not sep or not key.isidentifier():
            raise SceneError(f"{flag} {text!r}: expected KEY=VALUE, e.g. mesh=skfem or "
                             "gamma0=1.0")
        try:
            options[key] = tomllib.loads(f"v = {raw}")["v"]
        except tomllib.TOMLDecodeError:
            options[key] = raw
    return options


def _resolve_solver(args, scene=None) -> None:
    """``--solver`` not given: the formulation's declared solver (``ssn`` for mixed,
    ``newton`` for Nitsche; for a friction ``scene``, the first declaring its law)."""
    if getattr(args, "solver", None) is None:
        from rbbench.hf.components import default_solver
        from rbbench.scene.friction import friction_of

        law = friction_of(scene).law if scene is not None else "none"
        args.solver = default_solver(args.formulation, law=law)


def _add_option_args(p) -> None:
    p.add_argument("--backend-option", action="append", metavar="KEY=VALUE",
                   help="backend constructor option (repeatable), e.g. mesh=skfem "
                        "(ngsolve: one mesh with skfem)")
    p.add_argument("--formulation-option", action="append", metavar="KEY=VALUE",
                   help="formulation constructor option (repeatable), e.g. gamma0=1.0 "
                        "(nitsche)")
