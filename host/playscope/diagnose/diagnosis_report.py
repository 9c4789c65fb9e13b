"""HTML page of a diagnosis: verdict table, residual atlas before/after, loops measured against
simulated, time series; matplotlib figures embedded as PNG (base64), one self-contained file."""

from __future__ import annotations

import base64
import html
import io

import numpy as np

from ..base.atomic import HTML_GENERATOR


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    import matplotlib.pyplot as plt
    plt.close(fig)
    return "<img src='data:image/png;base64," + base64.b64encode(buf.getvalue()).decode() + "'/>"


def figures(data, res: dict, atlas_before: dict, atlas_after: dict) -> list[tuple[str, str]]:
    """(title, <img>) pairs: atlas panels before/after, hysteresis loops, residual over time."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs = []
    panels = [("by_travel_up", "travel since reversal, going up [mm]"), ("by_travel_down", "travel since reversal, going down [mm]"),
              ("by_time_since_reversal", "time since reversal [s]"), ("by_q", "q [mm]"), ("by_c", "c [deg]"),
              ("by_speed", "|dq/dt| [mm/s]"), ("by_wallclock", "time [s]")]
    if "by_u" in atlas_before:
        panels += [("by_u", "u [px]"), ("by_v", "v [px]")]
    fig, axs = plt.subplots(3, 4, figsize=(15, 9))
    for ax, (k, lab) in zip(axs.flat, panels):
        for at, name, st in ((atlas_before, "before", "-o"), (atlas_after, "after", "-s")):
            b = at[k]
            ax.plot(b["x"], b["rms"], st, ms=3, label=f"RMS {name}")
            ax.plot(b["x"], b["mean"], ":", label=f"mean {name}")
        ax.set_xlabel(lab)
        ax.set_ylabel("residual [deg]")
    ax = axs.flat[len(panels)]
    for at, name in ((atlas_before, "before"), (atlas_after, "after")):
        ax.semilogy(at["spectrum"]["f_hz"][1:], np.maximum(at["spectrum"]["psd"][1:], 1e-12), label=name)
    ax.set_xlabel("frequency [Hz]"); ax.set_ylabel("PSD [deg^2/Hz]")
    ax = axs.flat[len(panels) + 1]
    for at, name in ((atlas_before, "before"), (atlas_after, "after")):
        ax.plot(at["xcorr_velocity"]["lag_s"], at["xcorr_velocity"]["r"], label=name)
    ax.set_xlabel("lag [s]"); ax.set_ylabel("xcorr(residual, dc/dt)")
    axs.flat[0].legend(fontsize=7)
    for ax in list(axs.flat)[len(panels) + 2:]:
        ax.axis("off")
    fig.suptitle("Residual atlas on held-out rows: base model (before) and with the kept effects (after)")
    figs.append(("Residual atlas", _png(fig)))

    base, final = res["_fits"]["base"], res["_fits"]["final"]
    qm = np.interp(data.t_m - data.t_delay_s, data.t_int, data.q_int)
    fig, axs = plt.subplots(1, 2, figsize=(13, 4.5))
    for ax, f, name in ((axs[0], base, "base model"), (axs[1], final, "with kept effects")):
        ax.plot(qm, data.y_m, ".", ms=1.5, color="0.5", label="measured")
        ax.plot(qm, f.pred, "-", lw=0.7, label=name)
        ax.set_xlabel("q [mm]"); ax.set_ylabel("c [deg]"); ax.legend(fontsize=8)
    fig.suptitle("Hysteresis loops: measured against simulated")
    figs.append(("Loops", _png(fig)))

    fig, ax = plt.subplots(figsize=(13, 3.5))
    ax.plot(data.t_m, data.y_m - base.pred, lw=0.6, label="base")
    ax.plot(data.t_m, data.y_m - final.pred, lw=0.6, label="kept effects")
    # Shade the validation rows (blocks or a time range, whichever the split chose).
    ax.fill_between(data.t_m, 0, 1, where=res["_eval_mask"], transform=ax.get_xaxis_transform(), color="y",
                    alpha=0.15, label="validation")
    ax.set_xlabel("t [s]"); ax.set_ylabel("residual [deg]"); ax.legend(fontsize=8)
    figs.append(("Residual over time", _png(fig)))

    if "u" in data.extra:
        J = data.extra["J"]
        fig, ax = plt.subplots(figsize=(7, 5.5))
        step = max(1, data.t_m.size // 400)
        for f, col in ((base, "C0"), (final, "C1")):
            r = (data.y_m - f.pred)[::step]
            ax.quiver(data.extra["u"][::step], data.extra["v"][::step], (J[::step, 0] * r), (J[::step, 1] * r),
                      color=col, angles="xy", scale_units="xy", scale=0.2, width=0.002)
        ax.invert_yaxis(); ax.set_xlabel("u [px]"); ax.set_ylabel("v [px]")
        ax.set_title("Image-plane residual arrows (x5; blue base, orange kept effects)")
        figs.append(("Image-plane residuals", _png(fig)))
    return figs


def html_page(title: str, summary: dict, figs: list[tuple[str, str]]) -> str:
    """Self-contained HTML: the per-session verdict table then the figures."""
    rows = []
    for name, r in summary.items():
        kept = "<br>".join(
            f"{html.escape(k['effect'])}: " + ", ".join(f"{html.escape(p.split('.', 1)[1])} = {v[0]:.3g} &plusmn; {v[1]:.2g}"
                                                          for p, v in k["params"].items())
            + f" (held-out {k['rmse_before_deg']:.3f} &rarr; {k['rmse_after_deg']:.3f} deg, "
              f"{100 * k['share_of_excess_removed']:.0f} % of excess)"
            + (f"; cannot tell apart from {', '.join(k['indistinguishable_from'])}" if k["indistinguishable_from"] else "")
            for k in r["kept"]) or "&mdash;"
        rows.append(f"<tr><td>{html.escape(name)}</td><td>{r['noise_floor_deg']:.3f} ({html.escape(r['noise_method'])})</td>"
                    f"<td>{r['base']['rmse_heldout_deg']:.3f}</td><td>{r['final']['rmse_heldout_deg']:.3f}</td>"
                    f"<td><b>{html.escape(r['verdict'])}</b></td><td>{kept}</td></tr>")
    body = "".join(f"<h2>{html.escape(t)}</h2>{img}" for t, img in figs)
    return f"""<!doctype html><html><head><meta charset='utf-8'>{HTML_GENERATOR}<title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;margin:2em}} table{{border-collapse:collapse}} td,th{{border:1px solid #aaa;padding:4px 8px;vertical-align:top}}</style>
</head><body><h1>{html.escape(title)}</h1>
<table><tr><th>session</th><th>noise floor [deg]</th><th>held-out RMSE, base [deg]</th><th>with kept effects [deg]</th><th>verdict</th><th>kept effects</th></tr>
{''.join(rows)}</table>{body}</body></html>"""
