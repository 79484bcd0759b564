"""Navigation runs: initialisation (truth or static alignment), orchestration over
chunked records, error analysis against the truth, oscillation components, and the
linear error model / closed forms used to check the mechanization.

Error conventions (SI, ENU):

* attitude error ``phi`` with ``C_est = exp([phi x]) C_true`` (the rotation vector of
  :func:`inscal.core.attitude.small_angle_error`), so a level error of the computed
  frame about North is ``phi_N``; with this sign an East accelerometer bias ``b``
  settles at ``phi_N = -b/g`` (T&W ch. 12, tilt = -bias/g);
* velocity error ``v_est - v_true``; position error in metres East/North/Up
  ``[(lambda_est - lambda) (R_N + h) cos L, (L_est - L)(R_M + h), h_est - h]``.

Linear error model (phi-angle form, ENU, vertical channel held; T&W ch. 12, S16 eq. 17
without the vertical terms), derived for ``C_est = (I + [phi x]) C``::

    phi'  = -w_ie x phi - dw_en(dv) - dw_ie(dL) + C_s^n eps          dw_ie = W [0, -sin L, cos L] dL
    dv'   =  phi x f^n + C_s^n nabla - 2 w_ie x dv      (horizontal)   dw_en = [-dv_N/R_M, dv_E/R_N, dv_E tan L/R_N]
    dL'   =  dv_N / R_M,        dlambda' = dv_E / (R_N cos L)
"""

from __future__ import annotations

import csv
import json
import math
import warnings
from dataclasses import dataclass
from typing import Callable, Iterable

import h5py
import numpy as np

from inscal import SCHEMA_VERSION, __version__
from inscal.core.error_model import GimbalErrors, ImuErrors
from inscal.core.thermal import ThermalModel
from inscal.io.files import atomic_path
from inscal.nav.accuracy import NavErrors, navigation_errors, summarize
from inscal.nav.align import AlignConfig, AlignResult, align
from inscal.nav.strapdown import S_HREF, NavConfig, NavOutput, NavState, Strapdown
from inscal.nav.stream import (
    SampleStream,
    ThermalCompensation,
    compensated_chunks,
    thermal_chunks,
)


# ============================================================================ height reference
class HeightReference:
    """External height for the vertical channel (a barometer, a survey, a depth gauge).

    A constant ``height_m``, or a profile ``time_s``, ``height_m`` (linearly interpolated, held at its
    end values outside its span).  The damped vertical loop ("damped") tracks it, "hold" follows it;
    the navigator reads the reference once per :attr:`UPDATE_S` seconds.

    Parameters
    ----------
    height_m : float or array_like
        The height [m], or the heights of the profile.
    time_s : array_like, optional
        The profile's times [s], increasing (None: a constant height).

    Raises
    ------
    ValueError
        Heights or times that are not finite, not as many of each, or times that do not increase.

    Examples
    --------
    >>> from inscal.nav import HeightReference
    >>> ref = HeightReference([100.0, 110.0], [0.0, 10.0])
    >>> float(ref(5.0)), float(ref(60.0)), ref.span()
    (105.0, 110.0, (0.0, 10.0))
    >>> HeightReference(42.0).constant
    True
    """

    #: how often the navigator reads the reference [s] (the third-order loop's tau is ~100 s)
    UPDATE_S = 1.0

    def __init__(self, height_m=None, time_s=None):
        if time_s is None:
            h = float(height_m)
            if not math.isfinite(h):
                raise ValueError(f"reference height must be finite, got {height_m!r}")
            self.time = None
            self.height = np.array([h])
            return
        t = np.asarray(time_s, dtype=float).ravel()
        h = np.asarray(height_m, dtype=float).ravel()
        if t.size != h.size or t.size == 0:
            raise ValueError(f"height reference needs as many heights as times (got {t.size} and {h.size}), at least one")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(h))):
            raise ValueError("height reference: times and heights must be finite numbers")
        if t.size > 1 and np.any(np.diff(t) <= 0):
            k = int(np.argmax(np.diff(t) <= 0))
            raise ValueError(f"height reference: times must increase (row {k + 2}: {t[k + 1]:g} s after {t[k]:g} s)")
        self.time, self.height = t, h

    @property
    def constant(self) -> bool:
        """Whether the reference is one constant height (no time series)."""
        return self.time is None

    def __call__(self, t):
        if self.time is None:
            return np.full(np.shape(t), self.height[0]) if np.ndim(t) else float(self.height[0])
        return np.interp(t, self.time, self.height)

    def span(self) -> tuple[float, float] | None:
        """The (first, last) time [s] of the height series, or None for a constant."""
        return None if self.time is None else (float(self.time[0]), float(self.time[-1]))

    @classmethod
    def read_csv(cls, path) -> "HeightReference":
        """A CSV file with a header row naming the columns ``time_s`` and ``height_m`` (any order,
        other columns ignored; ``#`` comments allowed)."""

        with open(path, newline="", encoding="utf-8") as fh:
            rows = [r for r in csv.reader(line for line in fh if line.strip() and not line.lstrip().startswith("#"))]
        if not rows:
            raise ValueError(f"{path}: empty height reference (expected a header time_s,height_m and rows)")
        head = [c.strip() for c in rows[0]]
        if "time_s" not in head or "height_m" not in head:
            raise ValueError(f"{path}: the header must name the columns time_s and height_m, got {','.join(head)[:80]!r}")
        it, ih = head.index("time_s"), head.index("height_m")
        t, h = [], []
        for n, r in enumerate(rows[1:], start=2):
            try:
                t.append(float(r[it]))
                h.append(float(r[ih]))
            except (IndexError, ValueError):
                raise ValueError(f"{path}: row {n} is not two numbers time_s, height_m: {','.join(r)[:80]!r}") from None
        if not t:
            raise ValueError(f"{path}: no rows after the header")
        try:
            return cls(h, t)
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None


# ============================================================================ orchestration
@dataclass
class NavResult:
    """A navigation (:func:`navigate`): its output, its errors and what it was run with.

    Parameters
    ----------
    output : NavOutput
        The decimated navigation output (attitude, velocity, position at each output time).
    errors : NavErrors or None
        Its errors against the truth or the static site.
    summary : dict or None
        The summary figures of the errors (:func:`summarize`).
    alignment : AlignResult or None
        The alignment, when one was run.
    config : NavConfig
        The mechanization options.
    init : str
        How it started: ``"truth"``, ``"align"`` or ``"given"``.
    thermal : dict or None
        The thermal compensation applied (:meth:`ThermalCompensation.summary`), None without a
        thermal model.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.nav import chunks_of, navigate
    >>> from inscal.sim.scenarios import build
    >>> from inscal.sim.simulate import simulate
    >>> sc = build("static", duration_s=20.0, rate_hz=10.0)
    >>> res = navigate(chunks_of(simulate(sc, np.random.default_rng(0))), sc.rate_hz, sc.site, scenario=sc)
    >>> res.init, res.output.time.shape, res.alignment is None
    ('truth', (20,), True)
    """
    output: NavOutput
    errors: NavErrors | None
    summary: dict | None
    alignment: AlignResult | None
    config: NavConfig
    init: str
    #: the thermal compensation applied (:meth:`ThermalCompensation.summary`), None without a thermal model
    thermal: dict | None = None


def samples_needed(rate_hz: float, config: NavConfig | None = None, init="truth",
                   align_config: AlignConfig | None = None) -> tuple[int, str]:
    """The fewest samples :func:`navigate` can run on, and what they are for.

    One output row (:meth:`NavConfig.decimation` samples), after the alignment's samples with
    ``init="align"``.

    Parameters
    ----------
    rate_hz : float
        The sample rate [Hz].
    config : NavConfig, optional
        The mechanization options (their output rate).
    init : str or NavState
        How the navigation starts (``"align"`` needs the alignment's samples first).
    align_config : AlignConfig, optional
        The alignment's windows.

    Returns
    -------
    tuple of (int, str)
        The number of samples and what they are for, in words.

    Examples
    --------
    >>> from inscal.nav import AlignConfig, samples_needed
    >>> samples_needed(100.0)
    (100, 'one output at 1 Hz')
    >>> samples_needed(100.0, init="align", align_config=AlignConfig(coarse_time=60.0, fine_time=0.0))[0]
    6100
    """
    config = config or NavConfig()
    dt = 1.0 / rate_hz
    dec = config.decimation(dt)
    what = f"one output at {config.output_rate_hz:g} Hz"
    if isinstance(init, str) and init == "align":
        ac = align_config or AlignConfig()
        nc, nf = ac.samples(dt)
        return nc + nf + dec, f"the alignment ({ac.coarse_time:g} s coarse + {ac.fine_time:g} s fine) and {what}"
    return dec, what


def too_short(n: int, rate_hz: float, needed: int, what: str, task: str = "navigate") -> str:
    """The one line for a record too short for a task.

    Parameters
    ----------
    n : int
        The record's number of samples.
    rate_hz : float
        Its sample rate [Hz].
    needed : int
        The samples the task needs (:func:`samples_needed`).
    what : str
        What they are for.
    task : str
        The task, in words.

    Returns
    -------
    str
        The message.

    Examples
    --------
    >>> from inscal.nav import too_short
    >>> too_short(50, 100.0, 100, "one output at 1 Hz")
    '50 samples (0.5 s at 100 Hz), too short to navigate: it needs 100 samples (1 s) for one output at 1 Hz'
    """
    return (f"{n} sample{'s' if n != 1 else ''} ({n / rate_hz:.6g} s at {rate_hz:g} Hz), too short to {task}: it needs "
            f"{needed} samples ({needed / rate_hz:.6g} s) for {what}")


def navigate(chunks: Iterable, rate_hz: float, site, *, init="truth", scenario=None,
             params: ImuErrors | None = None, gimbal_model: GimbalErrors | None = None,
             config: NavConfig | None = None, align_config: AlignConfig | None = None,
             vref=None, progress: Callable[[float], None] | None = None,
             height_ref: "HeightReference | float | None" = None,
             thermal: "ThermalModel | ThermalCompensation | None" = None, temperature=None) -> NavResult:
    """Navigate a chunked record on a static site (strapdown mechanization, S16 compensation form).

    With a ``scenario``, the errors against its truth and a summary are computed; without one, the
    position and velocity errors against the static ``site``.

    Parameters
    ----------
    chunks : iterable
        ``(time, dtheta, dvel, gimbal)`` tuples (:func:`inscal.io.iter_chunks`, :func:`chunks_of`) or
        :class:`inscal.sim.simulate.Chunk` objects.
    rate_hz : float
        The sample rate [Hz].
    site : Site
        The known static site (latitude, longitude, height; its ``gravity_model`` is used throughout).
    init : str or NavState
        ``"truth"`` (needs ``scenario``), ``"align"`` (static coarse + fine alignment, the navigation
        continues from its end), or a :class:`~inscal.nav.strapdown.NavState` at the start.
    scenario : Scenario, optional
        The simulated scenario (its truth).
    params : ImuErrors, optional
        A calibration applied on the fly.
    gimbal_model : GimbalErrors, optional
        The gimbal non-orthogonality used to map the IMU attitude to the vehicle.
    config : NavConfig, optional
        The mechanization options (free or damped, vertical channel, output rate).
    align_config : AlignConfig, optional
        The alignment's windows and filter tuning (``init="align"``).
    vref : array_like or callable, optional
        The reference velocity of the damped mode (ENU [m/s], or a function of the chunk's times).
    progress : callable, optional
        Called with the time [s] reached after each chunk.
    height_ref : HeightReference or float, optional
        An external height for the vertical channel in place of the initial height ("damped" tracks
        it, "hold" follows it; "free" refuses it).
    thermal : ThermalModel or ThermalCompensation, optional
        The thermal model that goes with ``params`` (``params`` = the errors at its ``t_ref``): each
        sample is first mapped to ``t_ref`` at its ``temperature``.  Samples outside the model's range
        follow its policy (``warn``, ``clamp``: a RuntimeWarning says how many; ``error``: ThermalError).
    temperature : Temperature, float or callable, optional
        The samples' temperature (see :class:`ThermalCompensation`).

    Returns
    -------
    NavResult
        The output, its errors and summary, the alignment, and the thermal compensation applied.

    Raises
    ------
    ValueError
        No samples, too few for one output row, ``init="truth"`` without a scenario, an unknown
        ``init``, a temperature without a thermal model, or a height reference with a free vertical
        channel.
    ThermalError
        Samples outside the thermal model's range under ``out_of_range = "error"``.

    Examples
    --------
    A noise-free static IMU, aligned for 30 s, then navigated:

    >>> import numpy as np
    >>> from inscal.nav import AlignConfig, chunks_of, navigate
    >>> from inscal.sim.scenarios import build
    >>> from inscal.sim.simulate import simulate
    >>> sc = build("static", duration_s=40.0, rate_hz=10.0)
    >>> data = simulate(sc, np.random.default_rng(0))
    >>> res = navigate(chunks_of(data), sc.rate_hz, sc.site, init="align",
    ...                align_config=AlignConfig(coarse_time=10.0, fine_time=20.0))
    >>> res.init, float(res.output.time[0]), round(res.summary["final_position_error_m"], 6)
    ('align', 31.0, 0.0)
    """
    config = config or NavConfig()
    dt = 1.0 / rate_hz
    gravity = getattr(site, "gravity_model", None)
    stream = SampleStream(chunks)
    comp = None
    if isinstance(thermal, ThermalCompensation):
        comp = thermal
    elif thermal is not None:
        comp = ThermalCompensation(thermal, params, temperature, rate_hz)
    elif temperature is not None:
        raise ValueError("a temperature was given without a thermal model to apply it with")
    if comp is not None:
        # thermal model first (to t_ref), then the base errors, exactly as the calibration modelled them
        stream = SampleStream(thermal_chunks(stream.chunks(), comp))
    if params is not None and (params.has_asynchrony or np.any(params.accel_lever_arm - np.diag(np.diag(params.accel_lever_arm)))):
        # sample-to-sample terms (time asynchrony, tangential size effect) need the next sample:
        # compensate ahead of the kernel exactly as the systematic calibration does
        stream = SampleStream(compensated_chunks(stream.chunks(), params, dt))
        params = None
    head = stream.peek()
    if head is None or head[0].shape[0] == 0:
        raise ValueError("record has no samples")
    t0 = float(head[0][0]) - dt  # time of the start of the first sample
    alignment = None
    if isinstance(init, NavState):
        state, k0, label = init, 0, "given"
    elif init == "truth":
        if scenario is None:
            raise ValueError("initialisation from truth needs the simulation scenario (record has no truth)")
        state, k0, label = NavState.from_truth(scenario, t0), 0, "truth"
    elif init == "align":
        alignment = align(stream, dt, site.latitude, site.longitude, site.height, align_config, params, t0=t0,
                          gravity=gravity)
        state, k0, label = alignment.state, alignment.k_end, "align"
    else:
        raise ValueError(f"init must be 'truth', 'align' or a NavState, got {init!r}")
    nav = Strapdown(state, dt, config, params, k0=k0, t0=t0, gravity=gravity)
    if alignment is not None and (align_config or AlignConfig()).apply_bias_estimates:
        nav.set_extra_bias(alignment.gyro_bias, alignment.accel_bias)
    if height_ref is not None and not isinstance(height_ref, HeightReference):
        height_ref = HeightReference(height_ref)
    if height_ref is not None and config.vertical == "free":
        raise ValueError("a height reference needs a damped (or held) vertical channel, not vertical 'free'")
    if height_ref is not None and height_ref.constant:
        nav.st[S_HREF] = height_ref.height[0]
    elif height_ref is not None:  # the kernel reads the profile once per UPDATE_S, at the middle of each block
        nav.set_height_reference(height_ref, max(1, round(HeightReference.UPDATE_S * rate_hz)))
    parts = []
    n_seen = k0
    for t, dth, dv, g in stream.chunks():
        n_seen += t.shape[0]
        vr = None
        if vref is not None:
            vr = vref(t) if callable(vref) else vref
        parts.append(nav.run(dth, dv, g, vr))
        if progress is not None:
            progress(float(t[-1]))
    out = NavOutput.concatenate(parts, release=True) if parts else None
    if out is None or out.time.size == 0:  # no output row: nothing to judge the navigation by
        raise ValueError(too_short(n_seen, rate_hz, *samples_needed(rate_hz, config, init, align_config)))
    # static base: position and velocity are known even without a simulation truth
    errors = navigation_errors(out, scenario, gimbal_model, site=site)
    summary = summarize(errors, site.latitude)
    tsum = None
    if comp is not None:
        tsum = comp.summary()
        msg = comp.message()
        if msg is not None:
            warnings.warn(msg, RuntimeWarning, stacklevel=2)
    return NavResult(out, errors, summary, alignment, config, label, tsum)


def write_nav(path, res: NavResult, meta: dict | None = None, overwrite: bool = False) -> None:
    """Write a navigation result to HDF5 (SI datasets, atomic; see ``inscal navigate``)::

        /time (N,) s; /quaternion (N,4) C_s^n scalar-first; /velocity (N,3) m/s ENU;
        /position (N,3) lat rad, lon rad, h m; /vehicle_attitude (N,3) rad roll/pitch/yaw;
        /gimbal (N,2) rad (if recorded); /errors/{position,velocity[,attitude,vehicle]};
        attrs: kind="inscal-navigation", schema_version, mode, vertical, init, meta (JSON), summary (JSON).

    The output is published whole or not at all.

    Parameters
    ----------
    path : str or pathlib.Path
        The HDF5 file to write.
    res : NavResult
        The navigation (:func:`navigate`).
    meta : dict, optional
        What to record of how it was run (JSON-ready).
    overwrite : bool
        Replace an existing file; otherwise one is refused (FileExistsError).

    Examples
    --------
    >>> import h5py
    >>> import numpy as np
    >>> from inscal.nav import chunks_of, navigate, write_nav
    >>> from inscal.sim.scenarios import build
    >>> from inscal.sim.simulate import simulate
    >>> sc = build("static", duration_s=5.0, rate_hz=10.0)
    >>> res = navigate(chunks_of(simulate(sc, np.random.default_rng(0))), sc.rate_hz, sc.site, scenario=sc)
    >>> write_nav("nav.h5", res, {"record": "memory"})
    >>> with h5py.File("nav.h5", "r") as h5:
    ...     print(h5.attrs["kind"], h5["position"].shape)
    inscal-navigation (5, 3)
    """



    def _js(o):
        return json.dumps(o, default=lambda v: v.tolist() if hasattr(v, "tolist") else str(v))

    out = res.output
    with atomic_path(path, overwrite=overwrite) as tmp:
        with h5py.File(tmp, "w") as h5:
            h5.attrs["kind"] = "inscal-navigation"
            h5.attrs["schema_version"] = SCHEMA_VERSION
            h5.attrs["inscal_version"] = __version__
            h5.attrs["mode"] = res.config.mode
            h5.attrs["vertical"] = res.config.vertical
            h5.attrs["init"] = res.init
            h5.attrs["meta"] = _js(meta or {})
            h5.attrs["summary"] = _js(res.summary or {})
            h5.attrs["units"] = json.dumps({"time": "s", "quaternion": "1", "velocity": "m/s", "position": "rad,rad,m",
                                            "vehicle_attitude": "rad", "gimbal": "rad", "errors/position": "m",
                                            "errors/velocity": "m/s", "errors/attitude": "rad", "errors/vehicle": "rad"})
            h5["time"] = out.time
            h5["quaternion"] = out.quaternion
            h5["velocity"] = out.velocity
            h5["position"] = out.position
            gm = None
            if meta and meta.get("gimbal_nonorthogonality_rad"):
                gm = GimbalErrors(meta["gimbal_nonorthogonality_rad"])
            h5["vehicle_attitude"] = out.vehicle_attitude(gm)
            if out.gimbal is not None:
                h5["gimbal"] = out.gimbal
            if res.errors is not None:
                g = h5.create_group("errors")
                g["position"] = res.errors.position
                g["velocity"] = res.errors.velocity
                if res.errors.attitude is not None:
                    g["attitude"] = res.errors.attitude
                    g["vehicle"] = res.errors.vehicle
