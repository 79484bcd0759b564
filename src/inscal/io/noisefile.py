"""``noise.toml``: an identified noise model (:class:`inscal.core.noise_models.NoiseModel`) in field units.

Layout (IEEE Std 952-2020 units for gyros, IEEE Std 1293-2018 for accelerometers; every value
carries its unit in a ``<name>_unit`` key, converted in :mod:`inscal.core.units`)::

    format = "inscal-noise"
    version = 1
    rate_hz = 100.0                      # the rate the model was identified at (its discrete forms)
    [[channel]]
    name = "gx"                          # gx gy gz (gyro) ax ay az (accelerometer), or any name
    kind = "gyro"
    model = "QN+WN+GM"
    [[channel.term]]
    type = "WN"                          # QN WN BI RW DR GM
    n = 0.0021
    n_unit = "deg/sqrt(h)"
    n_lower_95 = 0.0020                  # optional: the 95 % interval of the identification
    n_upper_95 = 0.0022
"""

from __future__ import annotations

import math
from pathlib import Path

import tomli_w

from inscal.core import noise_models as nm
from inscal.core import units
from inscal.io.files import atomic_path
from inscal.io.tomlfile import read_toml

FORMAT, VERSION = "inscal-noise", 1
#: the quantity kind of each parameter (core.units.KIND), per sensor kind
PARAM_KIND = {
    "gyro": {"q": "angle", "n": "arw", "b": "rate", "k": "rrw", "r": "rate-ramp", "sigma": "rate", "tc": "time"},
    "accel": {"q": "velocity", "n": "vrw", "b": "accel", "k": "arrw", "r": "accel-ramp", "sigma": "accel",
              "tc": "time"},
}
CLASSES = {cls.code: cls for cls in nm.PROCESSES}


class NoiseFileError(ValueError):
    """A noise.toml that cannot be read (one line)."""


def noise_document(model: nm.NoiseModel, intervals: dict | None = None, meta: dict | None = None) -> dict:
    """The TOML document of ``model``; ``intervals[channel][i][param] = (lower, upper)`` in SI, optional."""
    chans = []
    for ci, ch in enumerate(model.channels):
        fu = nm.FIELD_UNITS[ch.kind]
        terms = []
        for ti, t in enumerate(ch.terms):
            d = {"type": t.code}
            for p in t.params:
                u = fu[p]
                d[p] = float(units.from_si(float(getattr(t, p)), u))
                d[f"{p}_unit"] = u
                iv = (intervals or {}).get(ch.name, {}).get(ti, {}).get(p)
                if iv is not None:
                    d[f"{p}_lower_95"] = float(units.from_si(float(iv[0]), u))
                    d[f"{p}_upper_95"] = float(units.from_si(float(iv[1]), u))
            if t.code == "BI":
                d["f0"], d["f0_unit"] = float(t.f0), "Hz"
            terms.append(d)
        chans.append({"name": ch.name, "kind": ch.kind, "model": ch.model, "term": terms})
    doc = {"format": FORMAT, "version": VERSION, "rate_hz": float(model.rate_hz)}
    if meta:
        doc["meta"] = {k: v for k, v in meta.items() if v is not None}
    doc["channel"] = chans
    return doc


def write_noise(path, model: nm.NoiseModel, intervals: dict | None = None, meta: dict | None = None,
                overwrite: bool = False) -> None:
    """Write ``model`` to ``path`` (atomic; refuses an existing file unless ``overwrite``)."""
    text = ("# inscal noise model: IEEE Std 952-2020 (gyro) and 1293-2018 (accelerometer) units\n"
            + tomli_w.dumps(noise_document(model, intervals, meta)))
    with atomic_path(Path(path), overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")


def model_from_document(doc: dict, where: str = "noise model") -> nm.NoiseModel:
    """The :class:`NoiseModel` of a parsed document (or of a scenario's ``[noise]`` table of this layout)."""
    if doc.get("format", FORMAT) != FORMAT:
        raise NoiseFileError(f"{where}: format {doc.get('format')!r} is not {FORMAT!r}")
    rate = doc.get("rate_hz")
    if not isinstance(rate, (int, float)) or not rate > 0:
        raise NoiseFileError(f"{where}: rate_hz must be a positive number of Hz")
    chans = doc.get("channel")
    if not isinstance(chans, list) or not chans:
        raise NoiseFileError(f"{where}: no [[channel]] table")
    out = []
    for c in chans:
        name, kind = c.get("name"), c.get("kind")
        if not isinstance(name, str) or kind not in PARAM_KIND:
            raise NoiseFileError(f"{where}: each [[channel]] needs a name and kind = 'gyro' or 'accel'")
        terms = []
        for t in c.get("term", []):
            cls = CLASSES.get(t.get("type"))
            if cls is None:
                raise NoiseFileError(f"{where}: channel {name}: unknown term type {t.get('type')!r} "
                                     f"(known: {', '.join(CLASSES)})")
            kw = {}
            for p in cls.params:
                v, u = t.get(p), t.get(f"{p}_unit")
                if not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0 or not isinstance(u, str):
                    raise NoiseFileError(f"{where}: channel {name} term {cls.code}: {p} must be a finite number "
                                         f">= 0 with its {p}_unit")
                try:
                    kw[p] = float(units.to_si(float(v), u, PARAM_KIND[kind][p]))
                except units.UnitError as exc:
                    raise NoiseFileError(f"{where}: channel {name} term {cls.code}: {exc}") from None
            if cls is nm.BiasInstability:
                kw["f0"] = float(t.get("f0", 0.5 * rate))
            if cls is nm.GaussMarkov and not kw["tc"] > 0:
                raise NoiseFileError(f"{where}: channel {name}: a Gauss-Markov correlation time must be > 0")
            terms.append(cls(**kw))
        out.append(nm.ChannelNoise(name, kind, tuple(terms)))
    return nm.NoiseModel(tuple(out), float(rate))


def intervals_of(doc: dict) -> dict:
    """``{channel: {term index: {param: (lower, upper)}}}`` in the file's field units, from a document's
    ``<param>_lower_95`` / ``<param>_upper_95`` keys (absent where the file has none)."""
    out: dict = {}
    for ch in doc.get("channel", []):
        for i, t in enumerate(ch.get("term", [])):
            for key, lo in t.items():
                if key.endswith("_lower_95") and f"{key[:-9]}_upper_95" in t:
                    out.setdefault(ch.get("name"), {}).setdefault(i, {})[key[:-9]] = (lo, t[f"{key[:-9]}_upper_95"])
    return out


def read_noise(path) -> tuple[nm.NoiseModel, dict]:
    """``(model, meta)`` of a noise.toml; NoiseFileError with one line otherwise."""
    doc = read_toml(path, NoiseFileError, "noise model file")
    return model_from_document(doc, str(path)), dict(doc.get("meta", {}))
