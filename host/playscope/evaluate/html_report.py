"""HTML report: one self-contained file, matplotlib figures embedded as base64 PNG.

Figures (paper numbering): the hysteresis characteristic with the fitted envelopes
f2 = f(z_up), f1 = f(z_down) and the centre line f_remain (Figs. 6, 9); B(q) samples with
the spline and its knots (Fig. 8); predictions against the measurement over time and their
errors (Figs. 10, 11); the compensation result (Fig. 12). Tables: Table I and the
compensation rows (playscope.evaluate.prediction.format_table, rendered as HTML).
"""

from __future__ import annotations

import base64
import html
import io

import numpy as np

from ..fit import model
from ..base.atomic import HTML_GENERATOR, write_text_atomic
from ..fit.calibration import Calibration
from .prediction import Evaluation

COLORS = {"f_coarse": "black", "f_coarse+B": "tab:green", "f_remain+B": "goldenrod",
          "f_remain+B_fixed": "tab:purple", "f_coarse_inv": "black",
          "f_remain+B+PI": "tab:red", "f_remain+B+PI_fixed": "tab:brown"}


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def figures(cal: Calibration, ev: Evaluation) -> dict[str, str]:
    """{title: base64 PNG} for the four figures. cal: the calibration; ev: evaluate()'s result."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sr = ev.series
    out = {}
    unit = cal.actuator_unit
    q0, q1 = cal.q_range
    g = np.linspace(q0, q1, 400)

    # Figs. 6, 9: characteristic c(q) with the envelopes of eq. 2.
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(sr["q_f"], sr["c_meas"], ".", ms=2, color="0.55", label="measured (per frame)")
    f2, f1 = model.envelopes(g, cal.B, cal.f)
    ax.plot(g, f2, color="tab:red", label="f2 = f(z_up) (q increasing)")
    ax.plot(g, f1, color="tab:blue", label="f1 = f(z_down) (q decreasing)")
    ax.plot(g, cal.f(g), "--", color="goldenrod", label="f_remain (centre)")
    ax.plot(g, cal.f_coarse(g), ":", color="black", label="f_coarse")
    ax.set_xlabel(f"q ({unit})"); ax.set_ylabel("c (deg)"); ax.legend(fontsize=8); ax.grid(alpha=0.3)
    ax.set_title("Hysteresis characteristic and fitted envelope (Figs. 6, 9)")
    out["characteristic"] = _png(fig)

    # Fig. 8: B samples, spline, knots.
    fig, ax = plt.subplots(figsize=(7, 3.8))
    bs = cal.b_samples
    qm, b = np.asarray(bs["q_mean"], float), np.asarray(bs["b"], float)
    w = np.asarray(bs.get("weight", np.ones_like(b)), float)
    sc = ax.scatter(qm, b, c=w, cmap="viridis", vmin=0, vmax=1, s=18, label="onset samples (colour: robust weight)")
    fig.colorbar(sc, ax=ax, label="weight")
    ax.plot(g, cal.B(g), color="tab:red", label="B(q) spline")
    kn = np.unique(np.asarray(cal.B.spl.t, float))
    ax.plot(kn, cal.B(kn), "kx", label=f"knots ({kn.size})")
    ax.set_xlabel(f"q ({unit})"); ax.set_ylabel(f"B ({unit})"); ax.legend(fontsize=8); ax.grid(alpha=0.3)
    ax.set_title("Backlash width B(q) (Fig. 8)")
    out["backlash"] = _png(fig)

    # Figs. 10, 11: prediction vs measurement over time, and the errors.
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    t = sr["t_f"]
    if sr["Q"] is not None:
        a1.plot(t, sr["Q"][:, 0], color="0.4", lw=1.2, label="measured u")
        for m, Qh in sr["pred_Q"].items():
            if m == "f_remain+B_fixed":
                continue
            a1.plot(t, Qh[:, 0], color=COLORS[m], lw=0.8, label=m)
            a2.plot(t, np.hypot(*(Qh - sr["Q"]).T), color=COLORS[m], lw=0.8, label=m)
        a1.set_ylabel("u (px)"); a2.set_ylabel("distance error (px)")
    else:
        a1.plot(t, sr["c_meas"], color="0.4", lw=1.2, label="measured c")
        for m, c in sr["pred"].items():
            if m == "f_remain+B_fixed":
                continue
            a1.plot(t, c, color=COLORS[m], lw=0.8, label=m)
            a2.plot(t, np.abs(c - sr["c_meas"]), color=COLORS[m], lw=0.8, label=m)
        a1.set_ylabel("c (deg)"); a2.set_ylabel("|error| (deg)")
    a1.legend(fontsize=8, ncol=4); a2.set_xlabel("t (s)"); a1.grid(alpha=0.3); a2.grid(alpha=0.3)
    a1.set_title("Prediction against measurement (Fig. 10) and its error (Fig. 11)")
    out["prediction"] = _png(fig)

    # Fig. 12: compensation.
    fig, ax = plt.subplots(figsize=(9, 3.8))
    tc = sr["comp_t"]
    if sr["comp_c"]:
        ax.plot(tc, sr["comp_ref"], color="tab:red", lw=1.5, label="reference c*")
        for m in ("f_coarse_inv", "f_remain+B"):
            if m in sr["comp_c"]:
                ax.plot(tc, sr["comp_c"][m], color=COLORS[m], lw=0.8, label=f"plant with {m} command")
        ax.set_ylabel("c (deg)")
        ax.set_title("Open-loop compensation through the plant (Fig. 12)")
    else:
        for m, q in sr["comp_q"].items():
            ax.plot(tc, q, color=COLORS[m], lw=0.8, label=f"command {m}")
        ax.set_ylabel(f"q ({unit})")
        ax.set_title("Compensation commands (no plant available to run them)")
    ax.set_xlabel("t (s)"); ax.legend(fontsize=8); ax.grid(alpha=0.3)
    out["compensation"] = _png(fig)
    return out


def _md_table_to_html(md: str) -> str:
    """The Markdown from format_table() as HTML tables and paragraphs (escaped)."""
    parts, rows = [], []
    for line in md.splitlines() + [""]:
        if line.startswith("|"):
            if set(line.replace("|", "").strip()) <= set("-"):
                continue
            rows.append([html.escape(c.strip()) for c in line.strip("|").split("|")])
            continue
        if rows:
            head, body = rows[0], rows[1:]
            parts.append("<table><tr>" + "".join(f"<th>{c}</th>" for c in head) + "</tr>" +
                         "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in body) + "</table>")
            rows = []
        if line.strip():
            parts.append(f"<p>{html.escape(line)}</p>")
    return "\n".join(parts)


def write_report(path, cal: Calibration, ev: Evaluation, table_md: str, title: str = "playscope report") -> None:
    """Write the single-file HTML report atomically."""
    figs = figures(cal, ev)
    s = ev.summary
    caps = {"characteristic": "Hysteresis characteristic with the fitted envelope (Figs. 6, 9)",
            "backlash": "B(q): onset samples, cubic B-spline and its knots (Fig. 8)",
            "prediction": "Predictions against measurement over time (Figs. 10, 11)",
            "compensation": "Compensation result (Fig. 12)"}
    body = [f"<h1>{html.escape(title)}</h1>",
            f"<p>Session: <code>{html.escape(str(s.get('session')))}</code>; calibration: "
            f"<code>{html.escape(str(s.get('calibration')))}</code>; distal: {html.escape(s['distal_kind'])}; "
            f"t_delay {s['t_delay_s']:.3f} s; {s['frames_scored']} frames scored.</p>",
            "<h2>Table I: prediction errors</h2>", _md_table_to_html(table_md)]
    for k, cap in caps.items():
        body.append(f"<h2>{html.escape(cap)}</h2><img alt=\"{k}\" src=\"data:image/png;base64,{figs[k]}\">")
    doc = ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">" + HTML_GENERATOR + "<title>" + html.escape(title) +
           "</title><style>body{font-family:sans-serif;max-width:1000px;margin:auto}"
           "table{border-collapse:collapse}td,th{border:1px solid #999;padding:2px 6px}"
           "img{max-width:100%}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")
    write_text_atomic(path, doc)
