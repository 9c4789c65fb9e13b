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
