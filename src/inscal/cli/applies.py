"""Which options apply to what, in one table, checked for every command before it runs.

An option given on the command line that does not apply to the method, format or source it is given
with would be ignored without a word; :func:`check_command` refuses it in one line (exit 2) instead,
naming what it applies to.  The same place refuses a negative seed (numpy's generators take
``SeedSequence`` entropy >= 0), naming the option that carries it, a count below its bound (:data:`BOUNDS`:
``--workers 0``, ``--k 0``), a value out of its range (:data:`POSITIVE`, :data:`NON_NEGATIVE`: ``--minutes
0``), and an output whose name says another format than the one written (HDF5 under ``.txt``, TOML under
``.h5``).  The commands keep their own checks of values that depend on one another; this module holds the
"does it apply" rules and the ranges, so that a new method, format or option is added to one table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from inscal.cli.common import CliError
from inscal.io.formats import taking

SYSTEMATIC = ("systematic51", "systematic30", "unified")
NO_TABLE = ("multi-position", "ferraris")
PLATEAUS = ("thermal-plateaus",)
TABLE = ("six-position", "twelve-position", "n25", "joint") + SYSTEMATIC + PLATEAUS


@dataclass(frozen=True)
class Rule:
    """Option ``option`` (a parameter name) applies when ``applies(params)`` is true; ``where`` says to what."""

    option: str
    applies: Callable[[dict], bool]
    where: str


def _method(*methods: str) -> Callable[[dict], bool]:
    """The method, or the one thermal-plateaus runs on each plateau (``--per-plateau``), is one of ``methods``."""
    def applies(p: dict) -> bool:
        m = str(p.get("method") or "").strip().lower()
        inner = str(p.get("per_plateau") or "").strip().lower() if m in PLATEAUS else ""
        return m in methods or inner in methods
    return applies


def _fmt(*formats: str) -> Callable[[dict], bool]:
    return lambda p: str(p.get("fmt") or "").strip().lower() in formats


def _curve(p: dict) -> bool:
    return p.get("from_curve") is not None


#: the options of a calibration that apply to some methods only (calibrate and batch)
CALIBRATION = (
    Rule("filter_rate", _method(*SYSTEMATIC), "the systematic methods (systematic51, systematic30, unified)"),
    Rule("encoder_sigma", _method(*SYSTEMATIC), "the systematic methods (systematic51, systematic30, unified)"),
    Rule("encoder_latency", _method(*TABLE), "a turntable record's encoder angles (not multi-position, ferraris)"),
    Rule("skip_encoder_check", _method(*TABLE), "a turntable record's encoder angles (not multi-position, ferraris)"),
)
#: command -> the rules of its options
RULES: dict[str, tuple[Rule, ...]] = {
    "calibrate": CALIBRATION,
    "batch": CALIBRATION,
    "noise": (
        Rule("kind", _curve, "--from-curve (a record's channels are named gx..gz, ax..az: choose them with "
             "--channels)"),
    ),
    "import": (
        Rule("rates", _fmt(*taking("rates")), f"--format {' or '.join(taking('rates'))} (for csv/txt set kind = "
             "\"rates\" in the mapping; kf-gins and rosbag files say what they hold)"),
        Rule("dtype", _fmt(*taking("dtype")), f"--format {' or '.join(taking('dtype'))} (.bin)"),
    ),
}

#: counts and factors with a lower bound, whatever the command: parameter -> (bound, whether it is excluded)
BOUNDS: dict[str, tuple[float, bool]] = {
    "workers": (1, False), "mc_workers": (1, False), "runs": (1, False), "batch_size": (1, False), "k": (0, True),
    "candidates": (2, False), "population": (2, False),
}
#: command -> the options that take a positive number, and those that take a number >= 0 (None: not given)
POSITIVE: dict[str, tuple[str, ...]] = {
    "design": ("minutes", "max_rate", "max_accel", "arw", "vrw"),
    "observability": ("rate_hz", "arw", "vrw", "filter_rate_hz", "bi_tau"),
}
NON_NEGATIVE: dict[str, tuple[str, ...]] = {
    "observability": ("gyro_bi", "accel_bi", "gyro_rrw", "accel_rrw"),
}

#: command -> (output parameter, the format written, the suffixes that say it); a name with a suffix
#: of another format (:data:`OTHER_FORMATS`) is refused
OUTPUTS: dict[str, tuple[str, str, tuple[str, ...]]] = {
    "simulate": ("out", "an HDF5 record", (".h5", ".hdf5", ".he5")),
    "import": ("out", "an HDF5 record", (".h5", ".hdf5", ".he5")),
    "compensate": ("out", "an HDF5 record", (".h5", ".hdf5", ".he5")),
    "calibrate": ("out", "a TOML parameter file", (".toml",)),
}
#: suffixes that name a format (a name ending otherwise, or with none, says nothing)
OTHER_FORMATS = (".h5", ".hdf5", ".he5", ".toml", ".txt", ".csv", ".json", ".bin", ".mat", ".yaml", ".yml", ".html",
                 ".pdf", ".png", ".svg", ".sqlite", ".db", ".bag", ".mcap", ".npz", ".npy")


def _exists(path) -> bool:
    try:
        return Path(str(path)).exists()
    except (OSError, ValueError):  # a name too long, a NUL: the command's own checks name it
        return True


def flag(name: str, opts: dict[str, str]) -> str:
    """The long option of parameter ``name`` (``--mc-seed``), from the command's own declarations."""
    return opts.get(name, "--" + name.replace("_", "-"))


def check_command(command: str, params: dict, given: set[str], opts: dict[str, str]) -> None:
    """Refuse (:class:`CliError`, one line) what does not apply in a run of ``command``: ``params`` its
    parameters, ``given`` the names given on the command line, ``opts`` name -> long option."""
    for name in sorted(given):
        if (name == "seed" or name.endswith("_seed")) and isinstance(params.get(name), int) and params[name] < 0:
            raise CliError(f"{flag(name, opts)} must be a seed >= 0, got {params[name]}")
    for name, (bound, strict) in BOUNDS.items():
        v = params.get(name)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and not (
                math.isfinite(v) and (v > bound if strict else v >= bound)):
            raise CliError(f"{flag(name, opts)} must be {'>' if strict else '>='} {bound:g}, got {v}")
    for names, ok, what in ((POSITIVE, lambda v: v > 0, "a positive number"),
                            (NON_NEGATIVE, lambda v: v >= 0, "a number >= 0")):
        for name in names.get(command, ()):
            v = params.get(name)
            if v is not None and not (math.isfinite(v) and ok(v)):
                raise CliError(f"{flag(name, opts)} must be {what}, got {v:g}")
    for rule in RULES.get(command, ()):
        if rule.option in given and not rule.applies(params):
            what = (f"--method {params.get('method')}" if "method" in params else
                    f"--format {params.get('fmt')}" if "fmt" in params else "a record")
            raise CliError(f"{flag(rule.option, opts)} applies to {rule.where}, not to {what}: drop it")
    if command == "noise" and _curve(params) and "channels" in given and params.get("channels"):
        kind = str(params.get("kind") or "gyro")
        first = str(params["channels"]).split(",")[0].strip().lower()
        if first and first[0] in "ga" and {"g": "gyro", "a": "accel"}[first[0]] != kind:
            raise CliError(f"--channels {first} names an {'accelerometer' if first[0] == 'a' else 'gyro'} channel, "
                           f"--kind {kind} a {kind} curve: give the one that is true (--kind sets the units)")
    if command in OUTPUTS:
        name, what, suffixes = OUTPUTS[command]
        out = params.get(name)
        same = [v for k, v in params.items() if k != name and isinstance(v, Path) and out is not None
                and Path(v).absolute() == Path(out).absolute()]
        # an output that is an input or exists already (the database, a record): the command's own check says so
        if out is not None and not same and not _exists(out):
            sfx = Path(str(out)).suffix.lower()
            if sfx in OTHER_FORMATS and sfx not in suffixes:
                raise CliError(f"{flag(name, opts)} {out}: the command writes {what}, and the name says {sfx}: "
                               f"use a {' or '.join(suffixes)} name")


def check_context(ctx) -> None:
    """:func:`check_command` for the command of the click context ``ctx`` (``db add``: a subcommand with its
    group's name), its options given on the command line or in the environment."""
    from typer._click.core import ParameterSource  # typer's own click (vendored), whose context runs the command

    given = {n for n in ctx.params if ctx.get_parameter_source(n) in (ParameterSource.COMMANDLINE,
                                                                      ParameterSource.ENVIRONMENT)}
    opts = {p.name: max((o for o in p.opts if o.startswith("--")), key=len, default=p.opts[0])
            for p in ctx.command.params if getattr(p, "opts", None)}
    group = ctx.parent.info_name + " " if ctx.parent is not None and ctx.parent.parent is not None else ""
    check_command(group + (ctx.info_name or ""), dict(ctx.params), given, opts)
