"""Simulated recordings written as session folders: the simulator's configuration from a preset
and overrides, a simulated session (optionally with rendered video), or a recording with a
measured tip angle re-imaged through a virtual endoscope camera (docs/simulator.md).

Library side of `playscope simulate` and of the main job; it never imports the command line."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .config_check import check_config

TRAJ_DEFAULTS = {
    # speed None: the pacing rule (sim.core.paced_speed), filled in by sim_config.
    "excitation": {"kind": "excitation", "q_lo": -3.0, "q_hi": 3.0, "amp": 1.4, "speed": None, "duration_s": 120.0, "cycles": 2},
    "test": {"kind": "test", "q_lo": -3.0, "q_hi": 3.0, "amp": 1.6, "speed": 1.0, "duration_s": 200.0, "hold_s": 1.0},
    "ellipse": {"kind": "ellipse", "a_mm": 8.0, "b_mm": 3.0, "period_s": 20.0, "cycles": 3},
    "random_walk": {"kind": "random_walk", "q_lo": -3.0, "q_hi": 3.0, "speed": 0.8, "duration_s": 120.0},
}


def sim_config(preset_name: str = "stras", config_json: str | None = None, effects=(),
               no_preset_effects: bool = False, trajectory: str | None = None,
               duration_s: float | None = None, seed: int | None = None, kind: str | None = None):
    """SimConfig of a named preset with overrides: config_json (a file of SimConfig keys),
    effects (specs NAME[:p=v,...], added after the preset's own unless no_preset_effects),
    trajectory (a TRAJ_DEFAULTS kind), duration_s (ellipse: cycles of its period), seed, kind
    ("image" or "angle"). Errors: ValueError for an unknown preset or effect, OSError/JSON
    errors for the config file."""
    from .core import SimConfig, preset
    from .effects import parse_effect

    cfg = preset(preset_name)
    if config_json:
        cfg = _config_overrides(cfg, config_json)
    if no_preset_effects:
        cfg.effects = {}
    for spec in effects:
        name, params = parse_effect(spec)
        cfg.effects[name] = params
    if trajectory:
        cfg.trajectory = dict(TRAJ_DEFAULTS[trajectory])
    if duration_s:
        if cfg.trajectory["kind"] == "ellipse":
            cfg.trajectory["cycles"] = duration_s / cfg.trajectory.get("period_s", 20.0)
        else:
            cfg.trajectory["duration_s"] = duration_s
    if seed is not None:
        cfg.seed = seed
    if kind:
        cfg.distal_kind = kind
    if cfg.trajectory.get("kind") == "excitation" and cfg.trajectory.get("speed") is None:
        from .core import paced_speed

        cfg.trajectory["speed"] = paced_speed(cfg)  # recorded in session.json as the number used
    return cfg


_JSON_KIND = {"NoneType": "null", "str": "a string", "list": "a list", "int": "a number", "float": "a number",
              "bool": "a boolean"}


def _config_overrides(cfg, config_json):
    """cfg with the keys of the JSON object in the file config_json replaced. Errors:
    InputError naming the file for anything but an object of known keys whose values have
    the type of the preset's (a number for a number, an object for an object, ...), and,
    through check_config, for a nested key missing, unknown or of the wrong type or range."""
    from ..base.errors import InputError
    from ..io.session import read_json
    from .core import SimConfig

    new = read_json(Path(config_json), "SimConfig JSON")
    d = cfg.to_json()
    if not isinstance(new, dict):
        raise InputError(config_json, f"--config takes a JSON object of SimConfig keys, this file holds "
                         f"{_JSON_KIND.get(type(new).__name__, type(new).__name__)}; known keys: {', '.join(sorted(d))}")
    for k, v in new.items():
        if k not in d:
            raise InputError(config_json, f"unknown SimConfig key {k!r}; known keys: {', '.join(sorted(d))}")
        want = d[k]
        num = (int, float)
        ok = (v is None or want is None or (isinstance(want, bool) and isinstance(v, bool))
              or (isinstance(want, num) and not isinstance(want, bool) and isinstance(v, num)
                  and not isinstance(v, bool))
              or (type(want) in (str, list, dict) and isinstance(v, type(want))))
        if not ok:
            raise InputError(config_json, f"key {k!r}: expected {type(want).__name__} like the preset's "
                             f"{json.dumps(want)[:60]}, got {type(v).__name__} {json.dumps(v)[:60]}")
    d.update(new)
    check_config(d, config_json)
    try:
        out = SimConfig.from_json(d)
    except (TypeError, KeyError, ValueError, AttributeError) as e:
        raise InputError(config_json, f"not a valid SimConfig: {e}") from None
    from ..io.session import check_camera

    check_camera(out.camera(), config_json)  # K, dist, width, height: a lens that can image
    return out


# --------------------------------------------------------------------------- SimConfig checks
def reimage(src: str, cfg, seed: int = 0):
    """Session whose marker is the measured tip angle of ``src`` seen by cfg's camera (nominal
    hand-eye, distortion, delay t_delay_s, marker noise). Returns (session, c_frames, t_frames)."""
    from ..io.session import Session, load_session
    from .core import observe_image

    p = Path(src)
    if p.is_dir():
        rec = load_session(p)
    else:
        from ..io.importer import import_catheter
        rec = import_catheter(p)
    if rec.distal is None:
        raise ValueError(f"{src}: no measured angle (distal.csv) to re-image")
    cfg.q_per_rad = rec.robot.q_per_rad
    truth = {"t_s": rec.distal["t_s"], "c_deg": rec.distal["c_deg"]}
    from .core import distal_direction
    from .effects import EffectSet
    truth["dir"] = distal_direction(truth["c_deg"], tol=0.02)
    rng = np.random.default_rng(seed)
    obs = observe_image(cfg, truth, EffectSet(dict(cfg.effects)), rng)
    s = Session(actuator_unit=rec.actuator_unit, distal_kind="image", robot=cfg.robot(), encoder=dict(rec.encoder),
                camera=cfg.camera(), hand_eye=cfg.hand_eye(), t_delay_s=cfg.t_delay_s,
                marker={k: obs[k] for k in ("t_s", "u_px", "v_px")}, truth=truth,
                meta={"source": {"reimaged_from": str(src)}, "simulator": cfg.to_json()})
    return s, obs["c_deg"], obs["t_s"]


@dataclass
class SimulatedSession:
    """A session folder written by write_simulated: path, encoder rows, marker frames (None
    for an angle session), the video file (None without video)."""

    path: Path
    encoder_rows: int
    frames: int | None
    video: Path | None

    def to_json(self) -> dict:
        return {"session": str(self.path), "encoder_rows": self.encoder_rows, "frames": self.frames,
                "video": None if self.video is None else str(self.video)}

    def summary_line(self) -> str:
        msg = f"wrote {self.path}: {self.encoder_rows} encoder rows"
        if self.frames is not None:
            msg += f", {self.frames} frames"
        if self.video is not None:
            msg += f", video {self.video.name}"
        return msg


def write_simulated(cfg, out, video: bool = False, blind: bool = False, reimage_src: str | None = None,
                    overwrite: bool = False) -> SimulatedSession:
    """Simulate cfg (or re-image reimage_src through cfg's camera) into the session folder out,
    with video.avi + frames.csv when video. blind leaves the effect list out of session.json.
    Errors: FileExistsError for an existing folder without overwrite; see reimage()."""
    from ..base.atomic import atomic_path
    from ..io.session import write_session
    from .core import observe_image, simulate
    from .effects import EffectSet

    out = Path(out)
    if reimage_src:
        s, c_frames, t_frames = reimage(reimage_src, cfg, cfg.seed)
    else:
        s = simulate(cfg, blind=blind)
    if out.exists() and not overwrite:
        raise FileExistsError(f"{out}: exists (use overwrite)")
    v = None
    with atomic_path(out) as tmp:  # the session and its video appear together, or not at all
        write_session(s, tmp)
        if video:
            from .render import write_video
            if not reimage_src:
                obs = observe_image(cfg, s.truth, EffectSet(dict(cfg.effects)), np.random.default_rng(cfg.seed),
                                    with_noise=False)
                c_frames, t_frames = obs["c_deg"], obs["t_s"]
                cap = obs["t_capture_s"]
            else:
                cap = t_frames - cfg.t_delay_s
            dirs = np.interp(cap, s.truth["t_s"], s.truth["dir"]) if "dir" in s.truth else None
            tr = np.interp(cap, s.truth["t_s"], s.truth["translation_mm"]) if "translation_mm" in s.truth else None
            v = out / write_video(cfg, c_frames, t_frames, tmp, dirs, tr, cfg.effects).name
    return SimulatedSession(out, int(s.encoder["t_s"].size), None if s.marker is None else int(s.marker["t_s"].size), v)
