"""The uncertainty budget of a calibration (:class:`inscal.uncertainty.budget.Budget`, as stored: its
``to_dict()``) as text lines (``inscal db budget``, ``inscal calibrate --station``) and as the HTML
section of the certificate: per parameter component the table of its inputs (input, value,
distribution, u(x), sensitivity, contribution, share) and the combined and expanded uncertainty
with its coverage factor and coverage probability.  Every number is the stored one: printed with
:func:`inscal.report.html.fmt_num`, kept whole in the ``data-exact`` attribute of its cell."""

from __future__ import annotations

from inscal.report.html import display_unit, escape, fmt_num

#: the readable names of the budget's inputs
INPUT_TITLES = {
    "estimator (Type A)": "estimator (Type A)",
    "repeatability (Type A)": "repeatability (Type A)",
    "table_angle": "table angle",
    "table_rate": "table rate",
    "axis_wobble": "axis wobble",
    "axis_nonorthogonality": "axis non-orthogonality",
    "encoder_resolution": "encoder resolution",
    "gravity": "site gravity",
    "latitude": "site latitude",
    "height": "site height",
    "time_base": "time base",
    "temperature_stability": "chamber temperature stability",
}


def _dof(v) -> str:
    return "∞" if v is None else fmt_num(v, 3)


def summary_line(c: dict) -> str:
    """``label  value ± U unit (k, coverage) u_c, nu_eff; largest share``."""
    top = max(c["contributions"], key=lambda x: x["share"])
    return (f"  {c['label']:26s} {fmt_num(c['value'], 6)} ± {fmt_num(c['U'], 3)} {c['unit']} "
            f"(k = {c['k']:.3f}, {c['coverage'] * 100:g} %; u_c {fmt_num(c['u_c'], 3)}, nu_eff {_dof(c['dof_eff'])}; "
            f"largest: {top['input']} {top['share'] * 100:.0f} %)")


def mc_line(m: dict) -> str:
    """A component's JCGM 101 Monte Carlo: its coverage interval, the differences from the linear one, the verdict."""
    return (f"    JCGM 101: [{fmt_num(m['low'], 6)}, {fmt_num(m['high'], 6)}] {m['unit']} (u {fmt_num(m['u'], 3)}); "
            f"d_low {fmt_num(m['d_low'], 2)}, d_high {fmt_num(m['d_high'], 2)} against delta {fmt_num(m['delta'], 1)} "
            f"(+- {fmt_num(2 * m['s_num'], 2)} numerical): {m['verdict']}")


def mc_summary(mc: dict) -> str:
    """One line: the Monte Carlo's trials and how many components each verdict has."""
    counts: dict[str, int] = {}
    for m in mc["components"]:
        counts[m["verdict"]] = counts.get(m["verdict"], 0) + 1
    return (f"JCGM 101 Monte Carlo: {mc['runs']} trials (seed {mc['seed']}, {mc['batches']} batches); the linear "
            f"interval " + ", ".join(f"{v} in {n}" for v, n in sorted(counts.items())) + f" of {len(mc['components'])}"
            f" components (JCGM 101 section 8, tolerance at {mc['n_dig']} significant digit(s) of u_c)")


def budget_lines(budget: dict, full: bool = True) -> list[str]:
    """The budget as text: per component its summary line and, when ``full``, its table; the JCGM 101 Monte Carlo's
    interval and verdict below each component when the budget has one."""
    out = [f"uncertainty budget: station {budget['station']!r}, method {budget['method']}, "
           f"coverage {budget['coverage'] * 100:g} %"]
    mc = budget.get("monte_carlo")
    by_label = {m["label"]: m for m in mc["components"]} if mc else {}
    if mc:
        out.append("  " + mc_summary(mc))
    for c in budget["components"]:
        out.append(summary_line(c))
        if c["label"] in by_label:
            out.append(mc_line(by_label[c["label"]]))
        if not full:
            continue
        out.append(f"    {'input':38s} {'value':>16s} {'distribution':12s} {'u(x)':>10s} {'unit':8s} "
                   f"{'sensitivity':>11s} {'u_i(y)':>10s} {'share':>6s}")
        for x in c["contributions"]:
            value = "" if x["value"] is None else fmt_num(x["value"], 8) + " " + x.get("value_unit", "")
            stops = f" x{x['stops']}" if x["stops"] > 1 else ""
            out.append(f"    {x['input'] + stops:38s} {value:>16s} {x['distribution']:12s} {fmt_num(x['u'], 4):>10s} "
                       f"{x['unit']:8s} {fmt_num(x['sensitivity'], 4):>11s} {fmt_num(x['contribution'], 3):>10s} "
                       f"{x['share'] * 100:5.1f}%")
    out += [f"  note: {n}" for n in budget.get("notes", [])]
    return out


def _cell(value, text: str, cls: str = "num") -> str:
    return f"<td class='{cls}' data-exact='{escape(repr(value))}'>{escape(text)}</td>"


def component_table(c: dict, mc: dict | None = None) -> str:
    """The HTML table of one component's budget, with its u_c, nu_eff, k and U below (and the JCGM 101 Monte
    Carlo's interval and verdict, ``mc``, when there is one)."""
    unit = display_unit(c["unit"])
    head = ("<thead><tr><th>Input</th><th class='num'>Value</th><th>Distribution</th><th class='num'>u(x)</th>"
            f"<th class='num'>Sensitivity<br>({escape(unit)} / unit of x)</th><th class='num'>Contribution<br>"
            f"({escape(unit)})</th><th class='num'>Share</th></tr></thead>")
    rows = []
    for x in c["contributions"]:
        name = INPUT_TITLES.get(x["input"], x["input"])
        if x["stops"] > 1:
            name += f" ({x['stops']} stops, RSS)"
        share = f"{x['share'] * 100:.1f} %"
        vu = x.get("value_unit", "")
        value = ("<td class='num'>—</td>" if x["value"] is None else
                 _cell(x["value"], fmt_num(x["value"], 8) + (" " + display_unit(vu) if vu else "")))
        rows.append(f"<tr data-input='{escape(x['input'])}'><td>{escape(name)}</td>{value}"
                    f"<td>{escape(x['distribution'])}</td>"
                    f"{_cell(x['u'], fmt_num(x['u'], 4) + ' ' + display_unit(x['unit']))}"
                    f"{_cell(x['sensitivity'], fmt_num(x['sensitivity'], 4))}"
                    f"{_cell(x['contribution'], fmt_num(x['contribution'], 3))}"
                    f"{_cell(x['share'], share)}</tr>")
    foot = (f"<p class='small' data-label='{escape(c['label'])}'>Combined standard uncertainty "
            f"u<sub>c</sub> = <span data-key='u_c' data-exact='{escape(repr(c['u_c']))}'>{escape(fmt_num(c['u_c'], 4))}"
            f"</span> {escape(unit)}; effective degrees of freedom "
            f"<span data-key='dof_eff' data-exact='{escape(repr(c['dof_eff']))}'>{escape(_dof(c['dof_eff']))}</span>; "
            f"coverage factor k = <span data-key='k' data-exact='{escape(repr(c['k']))}'>{c['k']:.3f}</span>; "
            f"expanded uncertainty U = <span data-key='U' data-exact='{escape(repr(c['U']))}'>"
            f"{escape(fmt_num(c['U'], 3))}</span> {escape(unit)} (coverage probability {c['coverage'] * 100:g} %)</p>")
    if mc is not None:
        foot += (f"<p class='small' data-mc='{escape(c['label'])}'>JCGM 101 Monte Carlo: coverage interval "
                 f"[<span data-key='low' data-exact='{escape(repr(mc['low']))}'>{escape(fmt_num(mc['low'], 6))}</span>, "
                 f"<span data-key='high' data-exact='{escape(repr(mc['high']))}'>{escape(fmt_num(mc['high'], 6))}"
                 f"</span>] {escape(unit)}; the interval above is <b data-key='verdict'>{escape(mc['verdict'])}</b> "
                 f"(d<sub>low</sub> {escape(fmt_num(mc['d_low'], 2))}, d<sub>high</sub> "
                 f"{escape(fmt_num(mc['d_high'], 2))}, tolerance {escape(fmt_num(mc['delta'], 1))} {escape(unit)})</p>")
    return (f"<h3>{escape(c['label'])}</h3><table class='budget' data-label='{escape(c['label'])}'>{head}"
            f"<tbody>{''.join(rows)}</tbody></table>{foot}")


#: the budget tables' layout: small type, so that the seven columns fit an A4 page
CSS = ("table.budget { font-size: 7.5pt; margin-top: 1mm; } table.budget th { background: #e8e8e8; } "
       "table.budget td, table.budget th { padding: 0.6mm 1.2mm; } h3 { font-size: 9.5pt; margin: 3mm 0 0 0; "
       "break-after: avoid; }")

BUDGET_STATEMENT = (
    "The uncertainty of each result is evaluated after the GUM (JCGM 100:2008): the estimator's own uncertainty "
    "from the record's noise (Type A), the station's equipment and site as described below (Type B), with "
    "sensitivity coefficients by finite differences through the calibration method itself (the chamber's "
    "temperature stability through the unit's thermal model, where one is known: see the notes), and the unit's "
    "repeatability between runs where its history has one (Type A). The contributions combine in quadrature; "
    "the effective degrees of freedom follow Welch–Satterthwaite; the coverage factor k gives a coverage "
    "probability of 95 % (from the distribution of the linear model where a non-normal input is significant, "
    "Student's t otherwise).")


def budget_section(budget: dict, station: dict | None) -> str:
    """The certificate's budget section: the statement, the station's inputs and a table per component."""
    rows = []
    for name, d in ((station or {}).get("inputs") or {}).items():
        spread = (f"u = {d['uncertainty']}" if "uncertainty" in d else f"half-width {d['half_width']}")
        rows.append(f"<tr><td>{escape(INPUT_TITLES.get(name, name))}</td><td>{escape(d['distribution'])}, "
                    f"{escape(spread)} {escape(display_unit(d.get('uncertainty_unit', d['unit'])))}</td>"
                    f"<td>{escape(d['source'])}</td></tr>")
    station_table = ("<table class='kv'><thead><tr><th>Input</th><th>Distribution</th><th>Source</th></tr></thead>"
                     f"<tbody>{''.join(rows)}</tbody></table>") if rows else ""
    notes = "".join(f"<p class='small'>Note: {escape(n)}</p>" for n in budget.get("notes", []))
    mc = budget.get("monte_carlo")
    by_label = {m["label"]: m for m in mc["components"]} if mc else {}
    if mc:
        notes += f"<p class='small'>{escape(mc_summary(mc))}.</p>"
    return (f"<style>{CSS}</style><p class='small'>{escape(BUDGET_STATEMENT)}</p>"
            f"<p>Station: <b>{escape(budget['station'])}</b></p>"
            + station_table + notes + "".join(component_table(c, by_label.get(c["label"])) for c in budget["components"]))
