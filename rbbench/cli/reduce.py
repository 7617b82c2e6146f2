"""``rbbench reduce`` (offline stage and validation: ``result.json``) and
``rbbench online-scaling``: thin layers over :func:`rbbench.api.reduce`.

Every reduction flag defaults to "not given" (``argparse.SUPPRESS``): only the fields the
user typed reach the Python API, which takes the shared fields and the formulation's own
options alike and refuses an option of another formulation before any HF work; the error
names the flag as typed (:func:`flag`).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
from pathlib import Path
from typing import Any

from rbbench.cli.choices import component_arg
from rbbench.cli.common import _add_option_args, _backend_options, shown_default
from rbbench.cli.console import _print_reduce_summary, _Progress, print_linear_reduce
from rbbench.rb.config import OptionError, ReduceConfig
from rbbench.rb.friction.options import FrictionOptions
from rbbench.rb.mixed.options import MixedOptions
from rbbench.rb.nitsche.options import NitscheOptions
from rbbench.scene.loading import SceneError, load_scene
from rbbench.scene.parameters import FieldError

#: flags that are not ``--`` + the field's name with dashes
FLAGS = {"N": "-N", "R": "-R", "S": "-S", "k_pga_max": "--k-max", "n_jobs": "--jobs"}
#: integer flags that must be >= 1 (checked here, so that the message names the flag)
POSITIVE = ("N", "R", "S", "n_train", "n_valid", "n_jobs", "m_eim", "n_eim_train", "k_pga_max",
            "online_repeats", "gcns_per_iteration", "gcns_max", "gcns_patience", "bound_pod_max")
#: argparse destinations that are not reduction fields
_NOT_FIELDS = {"scene", "func", "command", "set", "out", "quiet", "backend_option",
               "formulation_option", "levels", "repeats", "baseline", "baseline_set",
               "match_sizes"}


def flag(field: str) -> str:
    """The command-line flag of a reduction field (``S`` -> ``-S``)."""
    return FLAGS.get(field, "--" + field.replace("_", "-"))


def reduce_fields(args: argparse.Namespace) -> dict[str, Any]:
    """The reduction fields the user gave, integer flags checked (>= 1)."""
    fields = {k: v for k, v in vars(args).items() if k not in _NOT_FIELDS}
    for key in POSITIVE:
        if key in fields and fields[key] < 1:
            raise SceneError(f"{flag(key)} {fields[key]}: must be an integer >= 1")
    if getattr(args, "backend_option", None):
        fields["backend_options"] = _backend_options(args.backend_option)
    if getattr(args, "formulation_option", None):
        fields["formulation_options"] = _backend_options(args.formulation_option,
                                                         "--formulation-option")
    return fields


def _flagged(exc: OptionError | FieldError) -> SceneError:
    """An option or value error with the flag the user typed in place of the field's
    name."""
    return SceneError(exc.message(flag))


def cmd_reduce(args: argparse.Namespace) -> int:
    from rbbench.api import reduce
    from rbbench.bench.guard import RunLock
    from rbbench.scene.linear import is_parabolic

    scene = load_scene(args.scene, overrides=args.set or [])
    lock = None
    if args.out:  # one writer per output directory, for the whole reduction
        Path(args.out).mkdir(parents=True, exist_ok=True)
        lock = RunLock(Path(args.out)).acquire()
    try:
        try:
            res = reduce(scene, progress=_Progress(args.quiet),
                         snapshot_progress=not args.quiet, **reduce_fields(args))
        except (OptionError, FieldError) as exc:
            raise _flagged(exc) from None
        s = res.summary()
        c = s["config"]
        path = _write_result(args, scene, _tag(c, res.hyper), s)
    finally:
        if lock is not None:
            lock.release()
    if c["formulation"] == "linear":
        print_linear_reduce(s, is_parabolic(scene), scene.data["discretization"]["inner_product"])
    else:
        from rbbench.hf.metrics import units_of

        _print_reduce_summary(s, c["formulation"], units_of(scene.data["scene"]["physics"]))
    print(f"wrote: {path}")
    return 0


def _tag(c: dict[str, Any], hyper: str) -> str:
    """The default output folder's suffix: the formulation's main choices."""
    if c["formulation"] == "linear":
        return "linear"
    if c["formulation"] == "nitsche":
        return f"nitsche_{hyper}"
    tag = f"{c['dual']}_{c['stabilizer']}"
    return tag + (f"_{c['friction_dual']}" if c.get("friction_dual") == "wedge" else "")


def _write_result(args, scene, tag: str, s: dict) -> Path:
    """``result.json`` of ``rbbench reduce`` (``--out``, default results/reduce/<scene>_<tag>)."""
    from rbbench.bench.guard import RunLock
    from rbbench.provenance import _jsonable, provenance

    out = Path(args.out) if args.out else Path("results") / "reduce" / f"{scene.name}_{tag}"
    out.mkdir(parents=True, exist_ok=True)
    text = json.dumps(_jsonable({**s, "provenance": provenance()}), indent=2) + "\n"
    # written whole and renamed into place: a link named result.json is replaced, never
    # followed; without --out the default directory is locked for the write
    tmp = out / f".result.{os.getpid()}.tmp"
    with contextlib.nullcontext() if args.out else RunLock(out):
        tmp.write_text(text)
        os.replace(tmp, out / "result.json")
    return out / "result.json"


def cmd_online_scaling(args: argparse.Namespace) -> int:
    from rbbench.rb.config import make_config
    from rbbench.studies.scaling import online_scaling, scaling_markdown

    try:
        rows = online_scaling(args.scene, make_config(**reduce_fields(args)),
                              tuple(args.levels), tuple(args.set or ()), repeats=args.repeats,
                              progress=_Progress(args.quiet), baseline=args.baseline,
                              baseline_overrides=tuple(args.baseline_set or ()),
                              match_sizes=args.match_sizes)
    except (OptionError, FieldError) as exc:
        raise _flagged(exc) from None
    print(scaling_markdown(rows))
    print("(online time: one reduced solve incl. the EIM evaluation; median and IQR over "
          "validation mus x repeats, models interleaved; ratios: median / the first level's "
          "and / the baseline scene's)")
    return 0


def _add_reduce_args(rd: argparse.ArgumentParser) -> None:
    """The reduction flags: the shared fields, then each formulation's options (the help
    says whose); none has a default here (the formulation's own applies, shown in the help by
    :func:`state_defaults`)."""
    rd.argument_default = argparse.SUPPRESS
    _add_option_args(rd)
    _add_shared_args(rd.add_argument_group("shared by every formulation"))
    _add_mixed_args(rd.add_argument_group("mixed formulation (frictionless and friction "
                                          "scenes)"))
    _add_friction_args(rd.add_argument_group("mixed formulation on friction scenes"))
    e = rd.add_argument_group("hyper-reduction (mixed, friction wedge, nitsche)")
    e.add_argument("--tol-eim", type=float,
                   help="EIM / DEIM / ECSW tolerance (relative training error)")
    e.add_argument("--m-eim", type=int,
                   help="cap on the number of EIM terms or cubature points (default: the "
                   "tolerance decides; nitsche's ECSW: at most "
                   "rbbench.rb.nitsche.offline.ECSW_POINTS_PER_MODE x N points)")
    e.add_argument("--n-eim-train", type=int, help="EIM training grid size (default: a "
                   "multiple of --n-train)")
    rd.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE", default=None,
                    help="override a scene value (repeatable)")


def _add_shared_args(g: Any) -> None:
    """The fields of :class:`rbbench.rb.config.ReduceConfig` (argument group ``g``)."""
    component_arg(g, "--formulation", "formulation",
                  "formulation (default mixed; linear on a linear scene)")
    component_arg(g, "--backend", "backend", "HF backend")
    component_arg(g, "--solver", "solver", "the HF solver of the snapshots (default: the "
                  "formulation's own: ssn for mixed, friction-ssn on a friction scene, "
                  "newton for nitsche; a linear scene has none)")
    component_arg(g, "--primal", "primal", "primal compressor")
    component_arg(g, "--hyper", "hyper", "hyper-reducer (eim on friction scenes: the EIM of "
                  "the friction rows, with the wedge model also a DEIM of the slip)",
                  extra={"auto": "the formulation's rule"})
    g.add_argument("-N", type=int, help="primal size (default: POD tolerance --tol-pod); "
                   "clipped to the number of training snapshots and to their numerical rank, "
                   "with a warning in result.json 'warnings' (N there: the size built)")
    g.add_argument("--tol-pod", type=float, help="POD energy tolerance")
    g.add_argument("--n-train", type=int, help="training parameters (default: the scene's)")
    g.add_argument("--n-valid", type=int, help="validation parameters (default: the scene's)")
    g.add_argument("--online-repeats", type=int,
                   help="timed online solves per validation parameter")
    g.add_argument("--jobs", type=int, dest="n_jobs",
                   help="processes for the HF snapshots (default: the CPUs)")
    g.add_argument("--cache-dir", help="HF snapshot cache")


def _add_mixed_args(m: Any) -> None:
    """The options of the mixed formulation (argument group ``m``)."""
    component_arg(m, "--dual", "dual", "dual compressor of the multiplier cone")
    m.add_argument("-R", type=int, help="maximal dual size (default: as many generators as "
                   "--tol-dual needs)")
    m.add_argument("--tol-dual", type=float, help="dual compressor tolerance on e_proj")
    component_arg(m, "--stabilizer", "stabilizer", "stabiliser of the primal space (one "
                  "building its space online, as supremizer: frictionless only)")
    m.add_argument("--delta-pga", type=float,
                   help="PGA tolerance on sigma_max (default: the rule of "
                   "rbbench.rb.compressors.pga_delta, written as result.json pga_delta)")
    m.add_argument("--k-max", type=int, dest="k_pga_max",
                   help="cap on the PGA dimension K (online primal size N + K; none: no cap)")
    m.add_argument("--exact-max-r", type=int, help="largest cone whose inf-sup constant is "
                   "computed exactly (larger: bounds)")
    m.add_argument("--online-method", help="frictionless: reduced solver auto, nnls, pdas "
                   "(condensed LCP), daqp (primal QP)")
    m.add_argument("--bound", help="frictionless: the certified error bound, auto (online "
                   "where the operators are affine, else evaluated with the HF operators at "
                   "each validation parameter), online (also under the contact EIM of a "
                   "two-body scene, at an offline cost of minutes) or hf (always with the HF "
                   "operators)")
    m.add_argument("--bound-pod-max", type=int, help="frictionless, --bound online on a "
                   "two-body scene: the most modes (leading eigenvectors of P_M^T X^-1 P_M and "
                   "POD) of the master half of B(mu)^T lam_N (fewer: a faster bound with a "
                   "larger rigorous remainder)")


def _add_friction_args(f: Any) -> None:
    """The options of the mixed formulation on friction scenes (argument group ``f``)."""
    f.add_argument("--friction-dual", choices=("auto", "collocation", "wedge", "seed"),
                   help="the dual model: auto (wedge on Coulomb scenes, with the friction EIM "
                   "when --hyper is auto; collocation on Tresca scenes), collocation (normal "
                   "cone, POD of lam_t, Coulomb collocated at GCNS nodes) or wedge (cones of "
                   "F lam_n +- lam_t, De Saxce's fixed point: the Coulomb cone at every "
                   "node); 'seed': old name of collocation (deprecated)")
    f.add_argument("-S", type=int, help="tangential size (collocation: POD of lam_t; wedge: "
                   "generators of the F lam_n - lam_t cone; default R)")
    f.add_argument("--gcns-per-iteration", type=int,
                   help="collocation: GCNS nodes added per iteration")
    f.add_argument("--gcns-max", type=int, help="collocation: GCNS iterations at most "
                   "(default: no cap; GCNS stops when no node is violated or all are in)")
    f.add_argument("--gcns-patience", type=int,
                   help="collocation: GCNS stops after this many increases of e_GCNS, keeping "
                   "the best set (1: stop at the first increase)")


#: the dataclasses declaring the reduction fields, and whose fields they are (``--help``)
DECLARED = ((ReduceConfig, "every formulation"), (MixedOptions, "mixed"),
            (FrictionOptions, "mixed on friction scenes"), (NitscheOptions, "nitsche"))


def field_defaults(name: str) -> dict[str, Any]:
    """``{whose: default}`` of the reduction field ``name`` in the dataclasses of
    :data:`DECLARED` that declare it with a default value. ``None`` (a rule, said in the
    help's words) is left out, unless another dataclass has a value: then it is shown as
    ``none`` beside it (``--k-max``: mixed none, friction 40)."""
    out = {}
    for cls, whose in DECLARED:
        for f in dataclasses.fields(cls):
            if f.name == name and f.default is not dataclasses.MISSING:
                out[whose] = f.default
    if all(v is None for v in out.values()):
        return {}
    return {k: ("none" if v is None else v) for k, v in out.items()}


def state_defaults(parser: argparse.ArgumentParser) -> None:
    """End the help of every flag without a default of its own (``argparse.SUPPRESS``) with
    the default of its field, read from :data:`DECLARED` (per formulation where they differ),
    so that the default is written once, in the dataclass."""
    for action in parser._actions:
        defaults = field_defaults(action.dest)
        if action.default is not argparse.SUPPRESS or not defaults:
            continue
        values = {repr(v) for v in defaults.values()}
        text = (shown_default(next(iter(defaults.values()))) if len(values) == 1 else
                "; ".join(f"{whose} {shown_default(v)}" for whose, v in defaults.items()))
        action.help = f"{action.help} (default: {text})"


def _add_reduce_parser(sub) -> None:
    rd = sub.add_parser("reduce", help="offline RB stage + online validation (mixed, nitsche "
                        "or linear formulation): errors, inf-sup constants, timings -> "
                        "result.json; an option of another formulation is an error")
    rd.add_argument("scene", help="scene name in problems/ or path to a .toml file")
    _add_reduce_args(rd)
    rd.add_argument("--out", default=None,
                    help="output directory (default results/reduce/<scene>_<choices>)")
    rd.add_argument("--quiet", action="store_true", default=False, help="no progress lines")
    rd.set_defaults(func=cmd_reduce)
    state_defaults(rd)


def _add_online_scaling_parser(sub) -> None:
    osc = sub.add_parser("online-scaling",
                         help="online time of one reduction at several mesh levels, timed "
                              "side by side (is it flat in the HF size?)")
    osc.add_argument("scene", help="scene name in problems/ or path to a .toml file")
    _add_reduce_args(osc)
    osc.add_argument("--levels", type=int, nargs="+", default=[0, 1],
                     help="mesh levels (discretization.level: sizes divided by 2**level), "
                          "one reduction each")
    osc.add_argument("--repeats", type=int, default=30,
                     help="online solves of every validation parameter per level, the "
                          "levels interleaved")
    osc.add_argument("--baseline", default=None, metavar="SCENE",
                     help="also reduce SCENE with the same flags and time it in the same loop "
                          "(e.g. the 2D counterpart of a 3D scene); its row comes first")
    osc.add_argument("--baseline-set", action="append", default=None,
                     metavar="SECTION.KEY=VALUE", help="override a value of the baseline scene "
                                                       "(repeatable)")
    osc.add_argument("--match-sizes", action="store_true", default=False,
                     help="build the first level first and cap the later levels' reduced "
                          "sizes (N, R, K, EIM terms) at its own, so that the ratios measure "
                          "the HF size alone (mixed formulation)")
    osc.add_argument("--quiet", action="store_true", default=False, help="no progress lines")
    osc.set_defaults(func=cmd_online_scaling, hyper="eim")
    state_defaults(osc)
