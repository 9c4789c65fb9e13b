"""Diagnosis of one record (the `playscope diagnose` command's work, library side): record
checks, the fit / validation / test split, attribution to library effects, the residual atlas
and, for image sessions, the image-geometry screen (docs/diagnosis.md)."""

from __future__ import annotations


def clean(res: dict) -> dict:
    """res without its private "_" keys (fits, masks, data), for JSON."""
    return {k: v for k, v in res.items() if not k.startswith("_")}


def combine_geometry(res: dict, session, data, fm, em) -> dict:
    """Run the image-geometry screen (geometry.py) and fold it into res["verdict"]: a geometry
    effect becomes the verdict when the c channel found nothing ("none")."""
    from .geometry import screen
    geo = screen(session, data, fm, em)
    res["geometry"] = geo
    if geo["kept"] and res["verdict"] == "none":
        res["verdict"] = geo["kept"][0]
    return geo


def diagnose_data(data, split: float = 0.5, progress=None, session=None, test_data=None) -> dict:
    """Record checks (split.thin_record), the fit / validation / test split (split.choose_split:
    the judged parts inside the fitted q range), attribute() (selection on validation, figures on
    test: the last part of the record, or test_data when given), the residual atlas before/after
    on the validation rows; for image sessions also the image-geometry screen."""
    from .attribute import attribute
    from .localise import atlas
    from .split import choose_split, thin_record

    data, notes = thin_record(data)
    rest = 1.0 - split
    sp = choose_split(data, (split, rest, 0.0) if test_data is not None else (split, rest / 2, rest / 2))
    if test_data is not None:
        test_data, tnotes = thin_record(test_data)
        notes += [f"test record: {n}" for n in tnotes]
    res = attribute(data, sp.fit, sp.val, progress=progress,
                    test_mask=None if test_data is not None else sp.test, test_data=test_data)
    res["split"] = sp.summary()
    res["record_notes"] = notes + sp.warnings
    if session is not None and session.distal_kind == "image":
        combine_geometry(res, session, data, sp.fit, sp.val)
    res["atlas_before"] = atlas(data, res["_fits"]["base"].pred, sp.val)
    res["atlas_after"] = atlas(data, res["_fits"]["final"].pred, sp.val)
    res["_eval_mask"] = sp.val
    res["_data"] = data
    return res


def summary_lines(name: str, res: dict) -> list[str]:
    """What `playscope diagnose` prints for one record's diagnosis (res: diagnose_data's dict):
    the noise floor, validation and test RMSE and verdict, the closest library effect, the
    record's warnings, each kept effect with its share of the excess, kept geometry effects."""
    r, t = res["final"], res["test"]
    where = "separate test record" if t["separate_record"] else "test part"
    out = [f"{name}: noise floor {res['noise_floor_deg']:.3f} deg ({res['noise_method']}); split {res['split']['method']}; "
           f"validation RMSE {res['base']['rmse_heldout_deg']:.3f} -> {r['rmse_heldout_deg']:.3f} deg; "
           f"{where} {t['rmse_base_deg']:.3f} -> {t['rmse_final_deg']:.3f} deg; verdict {res['verdict']}"]
    if res.get("hint"):
        out.append(f"  closest library effect (a hint, not a verdict): {res['hint']['effect']} -- {res['hint']['why']}")
    for n in res["record_notes"]:
        out.append(f"  warning: {n}")
    for k in res["kept"]:
        ps = ", ".join(f"{n.split('.', 1)[1]}={v[0]:.3g}±{v[1]:.2g}" for n, v in k["params"].items())
        ind = f"; cannot tell apart from {', '.join(k['indistinguishable_from'])}" if k["indistinguishable_from"] else ""
        ab = "".join(f"; {n} at its {b} bound" for n, b in k.get("at_bounds", {}).items())
        out.append(f"  + {k['effect']} ({ps}): {k['rmse_before_deg']:.3f} -> {k['rmse_after_deg']:.3f} deg, "
                   f"{100 * k['share_of_excess_removed']:.0f} % of the excess over the noise floor{ind}{ab}")
    for g in res.get("geometry", {}).get("screen", []):
        if g["kept"]:
            out.append(f"  + {g['effect']} ({g['param']}={g['value']:.3g}): path residual "
                       f"{res['geometry']['base_px']['heldout']:.3f} -> {g['heldout_px']:.3f} px (held out)")
    return out
