"""The estimation chain as functions (paper Fig. 4): session -> track -> calibrate -> tables ->
flash -> evaluate -> report, each reading and writing the same files as its `playscope` command
and returning a typed result.

The commands in playscope/commands/ parse arguments, call these and print ``result.line()``
(one line, what the command prints) and write ``result.to_json()`` (its ``--json`` document);
the main job (mainjob.py) and the benches call them directly. Nothing here reads
argv or prints: warnings are in the results, progress goes to a callback.

Errors: InputError naming the file (bad or missing input), FileExistsError for an output that
exists without overwrite, RuntimeError for a failed board check (flash).
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .base.errors import InputError

if TYPE_CHECKING:  # annotations only: a command's --help imports this module, not numpy's fits
    from .fit.calibration import Calibration


# --------------------------------------------------------------------------- track
# The track step is the io layer's (evaluate/real_eval.py runs it too, below the pipeline).
from .io.marker_track import Tracked, track_session  # noqa: E402,F401


# --------------------------------------------------------------------------- calibrate
@dataclass
class Calibrated:
    """calibrate_session's result: the calibration file written and its content."""

    path: str  # as given (printed as given)
    cal: Calibration
    notes: list = field(default_factory=list)  # the session loader's repairs (session.notes)

    @property
    def warnings(self) -> list[str]:
        """The loader's repairs, then the calibration's own warnings."""
        return list(self.notes) + self.cal.warnings

    def line(self) -> str:
        cal = self.cal
        b = cal.B(np.linspace(*cal.q_range, 200))
        return (f"{self.path}: {cal.n_b_samples} B samples from {cal.reversals} reversals "
                f"({', '.join(f'{k} {v}' for k, v in cal.onset_reasons.items() if v)}); "
                f"B {b.min():.3g}..{b.max():.3g} {cal.actuator_unit}, t_delay {cal.t_delay_s:.3f} s; "
                f"model {model_text(cal)}")

    def to_json(self) -> dict:
        cal = self.cal
        b = cal.B(np.linspace(*cal.q_range, 200))
        refine = cal.onset_refine or {}
        return {"calibration": self.path, "reversals": cal.reversals, "b_samples": cal.n_b_samples,
                "onset_reasons": cal.onset_reasons, "t_delay_s": cal.t_delay_s,
                "fps_frames": cal.fps_frames, "B_range": [float(b.min()), float(b.max())],
                "t_delay": refine.get("t_delay"), "ringing": refine.get("ringing"),
                "b_inconsistent": len(cal.b_inconsistent), "warnings": cal.warnings,
                "model": "play" if cal.transition.is_play else "pi", "operators": cal.transition.n}


def model_text(cal: Calibration) -> str:
    """'play' or 'play (b B) + PI, n operators (r <= ...)', with the CV error of the choice when
    calibrate made one (transition.choose_model)."""
    tr, ch = cal.transition, cal.model_choice
    txt = "play" if tr.is_play else (f"play ({tr.b_scale:g} B) + PI, {tr.n} operators (r <= {tr.r[-1]:.3g}"
                                     + (", thresholds proportional to B(q))" if tr.tmap is not None else ")"))
    if ch:
        from .fit.transition import picked_candidate

        pick = picked_candidate(ch)
        play = next((c for c in ch["candidates"] if c["n"] == 1), None)
        if pick:
            txt += f", CV RMSE {pick['cv_rmse_deg']:.3g} deg"
        if pick and play and pick is not play:
            txt += f" (play {play['cv_rmse_deg']:.3g})"
    return txt


def calibrate_session(session_dir, out, n_ctrl: int = 14, f_method: str = "lsq", fps: float | None = None,
                      t_delay_s: float | None = None, t_delay_from: str = "data",
                      hysteresis: float | None = None, threshold: float | None = None,
                      model_kind: str = "auto", progress=None) -> Calibrated:
    """calibration.calibrate on the session folder or recording file (importer.load_recording), saved to out (docs/calibration-format.md).
    threshold: the onset threshold T per frame (px or deg), default automatic; progress: a tqdm-like factory for the reading's bar, or None."""
    from .fit.calibration import calibrate
    from .io.importer import load_recording

    s = load_recording(session_dir, progress)
    notes = list(s.notes)  # what the loader repaired (repeated or backward stamps, a held sensor)
    ov = {"threshold": threshold} if threshold is not None else None
    cal = calibrate(s, n_ctrl, f_method, fps, t_delay_s, hysteresis, ov, t_delay_from=t_delay_from,
                    model_kind=model_kind)
    cal.save(out)
    return Calibrated(os.fspath(out), cal, notes)


# --------------------------------------------------------------------------- tables
@dataclass
class TableWritten:
    """write_tables' result: the blob's path, the loaded table (tables.CalibTable) and the
    measured fixed-point errors {direct_c_deg_max, comp_q_max, f_inv_err, z_err}."""

    path: str  # as given
    table: object
    errors: dict
    adapted: str | None = None  # what write_tables changed to meet the precision ceiling, if anything

    def line(self) -> str:
        tab, err = self.table, self.errors
        return (f"{self.path}: {len(tab.blob)} bytes, crc32 {tab.cal.crc32:#010x}, {tab.cal.b.n} entries per grid, "
                f"{tab.n_ops} transition operators; "
                f"worst |c_fixed - c_float| {err['direct_c_deg_max']:.2e} deg, |q*_fixed - q*_float| {err['comp_q_max']:.2e}"
                + (f"; {self.adapted}" if self.adapted else ""))

    def to_json(self) -> dict:
        tab = self.table
        return {"table": self.path, "bytes": len(tab.blob), "crc32": int(tab.cal.crc32),
                "entries": int(tab.cal.b.n), "operators": tab.n_ops, "errors": self.errors, "adapted": self.adapted}


def write_tables(cal_path, out, entries: int | None = None, generation: int = 1,
                 f_coarse: bool = False, instrument: int | None = None) -> TableWritten:
    """Calibration file -> Q16.16 table blob at out (common/ps_table.h, laid out by the firmware's
    table_write()), loaded back with calib_load() and measured against the float model.
    f_coarse: store f_coarse (eq. 5) instead of f_remain (eq. 9); instrument: the id the table is
    bound to (layout 5; None: PST_INSTRUMENT_DEFAULT). A table that misses the
    precision ceiling (CALIB_ERR_PRECISION, or check_precision) is tried again on denser grids,
    up to PST_MAX_ENTRIES per grid (the only layout setting the board leaves free: the header's
    units and the weights' Q format are fixed by common/ps_table.h); what was changed is in
    TableWritten.adapted. Errors: InputError naming cal_path when the model cannot be tabulated;
    for a precision refusal at the densest grid, the quantity (f^-1's error when it is the one)
    and by how much it misses the ceiling."""
    from .base.atomic import write_bytes_atomic
    from .fit.calibration_check import load_calibration
    from .base.native import core
    from .fit.table_build import TableError, build_table, check_physical, check_precision, f_inverse_error, table_errors

    cal = load_calibration(cal_path)
    q_min, q_max = cal.q_range
    f = cal.f_coarse if f_coarse else cal.f
    tr = None if f_coarse else cal.transition
    B = cal.B if f_coarse else cal.B_model
    rl = None if f_coarse else cal.relax  # the chosen family's travel-domain relaxation (layout 4)
    lib = core()[1]
    n_max = int(lib.PST_MAX_ENTRIES)
    tries = [entries] if entries else [n_max]
    while tries[-1] < n_max:
        tries.append(min(2 * tries[-1], n_max))
    adapted = None
    for k, n in enumerate(tries):
        try:
            check_physical(B, f, q_min, q_max, source=cal_path)
            tab = build_table(B, f, q_min, q_max, cal.actuator_unit, "coarse" if f_coarse else "remain",
                              generation, n, source=cal_path, transition=tr, relax=rl, instrument=instrument)
            err = table_errors(tab, B, f, q_min, q_max, tr, rl)
            check_precision(tab, err, f, q_min, q_max, source=cal_path)
        except TableError as e:
            precision = e.status == lib.CALIB_ERR_PRECISION or "precision ceiling" in e.message
            if not precision:
                raise
            if k + 1 < len(tries):
                continue
            raise TableError(cal_path, _precision_refusal(e, B, f, q_min, q_max, n, tr, f_inverse_error)) from None
        except (ValueError, OverflowError) as e:  # InputError passes through with its own file
            if isinstance(e, InputError):
                raise
            raise InputError(cal_path, f"cannot make a table of it: {' '.join(str(e).split())}") from None
        if k:
            adapted = f"grid density raised from {tries[0]} to {n} entries to meet the precision ceiling"
        break
    write_bytes_atomic(out, tab.blob)
    return TableWritten(os.fspath(out), tab, err, adapted)


def _precision_refusal(e, B, f, q_min, q_max, n, tr, f_inverse_error) -> str:
    """The refusal of a table no layout the board holds brings under the precision ceiling:
    the loader's reason, the quantity and by how much (f^-1's exact error when it is the one)."""
    msg = f"{e.message}; no layout the board holds meets it (tried up to {n} entries per grid)"
    try:
        fe = f_inverse_error(B, f, q_min, q_max, n)
    except Exception:  # noqa: BLE001  (the figure is extra information, never a second failure)
        return msg
    if fe["ratio"] > 1:
        return (msg + f": the inverse f table's error is {fe['f_inv_err']:.3g} against a ceiling of {fe['ceiling']:.3g} "
                f"actuator units ({fe['ratio']:.1f} times over): f is nearly flat somewhere; recalibrate "
                "(its slope floor) or give f more slope")
    which = "the play's envelopes (z_up/z_down)" if tr is None or tr.is_play else "the play's envelopes or the PI inverse"
    return msg + f": f^-1 is within it ({fe['ratio']:.2f} of the ceiling), so {which} miss it"


# --------------------------------------------------------------------------- flash
@dataclass
class Flashed:
    """flash_tables' result (device.flash.flash): generation and slot committed, bytes, crc32
    (hex), upload_s, readback_s, vectors (compensator steps compared bit for bit),
    round_trip_us."""

    generation: int
    slot: int
    bytes: int
    crc32: str
    upload_s: float
    readback_s: float
    vectors: int
    round_trip_us: float

    def line(self) -> str:
        from .board.flash import flash_line

        return flash_line(self.__dict__)

    def to_json(self) -> dict:
        return dict(self.__dict__)


def open_board(device: str = "virtual", flash_file=None, elf=None, address=None, vboard_args=()):
    """An open board.link.Link on device "virtual" (the desktop build as a process, flash_file its
    A/B flash, vboard_args its extra options), "qemu" (the link image under QEMU, elf) or "usb"
    (the board over libusb, in this process; address bus:device when several). The caller
    closes it. Errors: board.transport.TransportError when the board cannot be reached."""
    from .board.link import Link
    from .board.transport import open_transport

    return Link(open_transport(device, flash_file=flash_file, elf=elf, address=address, vboard_args=vboard_args))


def device_info(device: str = "virtual", flash_file=None, elf=None, address=None) -> dict:
    """The board's identification and table state (board.link.Link.info: firmware and protocol
    versions, active generation and slot, table CRC...) and its own limits (Link.limits_info:
    instrument, unit, travel, angle range, largest play), as the board reports them."""
    link = open_board(device, flash_file, elf, address)
    try:
        return {**link.info(), **link.limits_info()}
    finally:
        link.close()


def flash_tables(table, device: str = "virtual", flash_file=None, n_vectors: int = 200,
                 elf=None, address=None, usb_child: bool = True) -> Flashed:
    """Upload a table (a table file's path, or "builtin" for the firmware's built-in table) to a
    board, commit, read back, and check the board's compensator bit for bit against the host's
    run of the same C (board.flash.flash). device "virtual" (the desktop build as a process,
    flash_file its A/B flash), "qemu" or "usb". With usb_child (the main job, the tests) usb runs
    in a child process under the emulated USB device (board.usbemu: libusb's preload must be in
    a process from its start; flash_file is the emulated board's flash); without it, on the real
    board in this process. Errors: InputError for a bad table file (nothing is sent; checked
    before the board is opened), RuntimeError or board.link.DeviceError for a failed check or
    link."""
    from .board.table_check import read_table_file
    from .fit.table_build import builtin_table

    blob = builtin_table() if str(table) == "builtin" else read_table_file(table)
    if device == "usb" and usb_child:
        import json

        from .board import usbemu

        if str(table) == "builtin":
            raise InputError("builtin", "flash over the emulated USB device takes a table file, not the built-in table")
        r = usbemu.run([sys.executable, "-m", "playscope.board.flash", os.fspath(table),
                        "--vectors", str(n_vectors)], flash_file=os.fspath(flash_file) if flash_file else None)
        if r.returncode != 0:
            raise RuntimeError(f"flash over usb failed (exit {r.returncode}):\n{r.stdout}\n{r.stderr}")
        return Flashed(**json.loads(r.stdout.strip().splitlines()[-1]))
    from .board.flash import flash

    link = open_board(device, flash_file, elf, address)
    try:
        return Flashed(**flash(link, blob, n_vectors, log=lambda s: None))
    finally:
        link.close()


@dataclass
class PacedExcitation:
    """pace_excitation's result: exc the full Q0:Q1:AMP:ADV:V excitation (mm, mm/s), the frame
    rate and play range it was paced to (None when the speed was given), and vboard_args, the
    virtual board's --pace options (the board computes the same speed itself: fit.pacing)."""

    exc: str
    fps: float | None = None
    b_low_mm: float | None = None
    b_high_mm: float | None = None
    vboard_args: list = field(default_factory=list)

    def line(self) -> str:
        if self.fps is None:
            return f"excitation {self.exc}"
        return f"excitation {self.exc} (speed paced to {self.fps:g} frames/s, play {self.b_low_mm:g}..{self.b_high_mm:g})"


def pace_excitation(exc: str, fps: float | None = None, b_range: str | None = None, sim_plant: bool = False,
                    seed: int = 0, video: str | None = None) -> PacedExcitation:
    """The run-insitu excitation Q0:Q1:AMP:ADV[:V]: with V given, as is; without, its swing speed
    paced to the camera (fit.pacing, the board's rule: the smallest play taken up over
    EXC_PACE_FRAMES frames). The play range b_range "LO:HI" (mm) defaults, with sim_plant, to the
    simulated instrument's; fps defaults to the simulated camera's, a video file's, else 25.
    Errors: InputError when the speed is missing and no play range is known, or pacing refuses
    (fit.pacing.paced_exc's reason)."""
    from .fit.pacing import frame_period_us, paced_exc

    if len(exc.split(":")) == 5:
        return PacedExcitation(exc)
    if b_range is not None:
        b_low, b_high = (float(x) for x in b_range.split(":"))
    elif sim_plant:
        from .sim.core import play_range
        from .sim.plant import SimPlant, SimPlantConfig

        b_low, b_high = play_range(SimPlant(SimPlantConfig(seed=seed)).sim)
    else:
        raise InputError("--exc", "without a speed, the swing is paced to the camera and needs the expected play, "
                         "--b-range LO:HI (or give the speed as --exc Q0:Q1:AMP:ADV:V)")
    if fps is None:
        fps = 25.0
        if sim_plant:
            from .sim.plant import SimPlantConfig

            fps = SimPlantConfig().fps
        elif video is not None and not video.isdigit():
            import cv2

            cap = cv2.VideoCapture(video)
            fps = cap.get(cv2.CAP_PROP_FPS) or 25.0
            cap.release()
    try:
        full = paced_exc(exc, b_low, b_high, fps)
    except ValueError as e:
        raise InputError("--exc", str(e)) from None
    return PacedExcitation(full, fps, b_low, b_high, ["--pace", f"{b_low!r}:{b_high!r}:{frame_period_us(fps)}"])


# --------------------------------------------------------------------------- evaluate, report
@dataclass
class Evaluated:
    """evaluate_session's result: evaluate.Evaluation (summary: the `evaluate --json` document,
    series: what the report plots) and the calibration it judged."""

    evaluation: object
    cal: Calibration

    @property
    def summary(self) -> dict:
        return self.evaluation.summary

    def line(self) -> str:
        """Table I and the compensation table as Markdown (evaluate.format_table)."""
        from .evaluate.prediction import format_table

        return format_table(self.summary)

    def to_json(self) -> dict:
        return self.summary


def _warn_repairs(s) -> None:
    """The session loader's repairs (session.notes: repeated or backward time stamps, a held
    sensor), one `playscope: warning:` line each on stderr, as the commands print warnings."""
    for line in s.notes:
        print(f"playscope: warning: {line}", file=sys.stderr)


def table_mismatch(tab, cal, table_path, cal_path) -> str | None:
    """One line when the table tab is not this calibration's: its fixed-point model, run over
    the calibration's travel, misses the float model (f_remain with its transition, or
    f_coarse for a `tables --f-coarse` table) by more than the precision ceiling every table
    `tables` writes meets (table_build.check_precision); None when it matches."""
    from .fit.table_build import TableError, check_precision, table_errors

    q_min, q_max = cal.q_range
    why = None
    for B, f, tr, rl in ((cal.B_model, cal.f, cal.transition, cal.relax), (cal.B, cal.f_coarse, None, None)):
        try:
            check_precision(tab, table_errors(tab, B, f, q_min, q_max, tr, rl), f, q_min, q_max, source=table_path)
            return None
        except TableError as e:
            why = why or e.message.split(";")[0]
        except (ValueError, OverflowError) as e:
            why = why or str(e)
    return (f"{table_path}: does not match the calibration {cal_path} ({why}): a table of another calibration? "
            "the fixed-point rows score that table, not this calibration; rebuild it with playscope tables")


def evaluate_session(session_dir, cal_path, table_path=None, comp_duration_s: float = 60.0) -> Evaluated:
    """Table I and the compensation test (evaluate.evaluate) of the calibration at cal_path on
    the test session folder; table_path: a blob from write_tables for the fixed-point rows
    (default: built from the calibration)."""
    from .fit.calibration_check import load_calibration
    from .evaluate.prediction import evaluate
    from .io.importer import load_recording

    cal = load_calibration(cal_path)
    s = load_recording(session_dir)
    _warn_repairs(s)
    tab = None
    if table_path:
        from .fit.table_build import CalibTable

        from .board.table_check import read_table_file

        path = Path(table_path)
        # The checks `flash` makes (size, magic, CRC, the loader's rules): a table the board
        # would refuse is not scored as if it had been flashed.
        tab = CalibTable(read_table_file(path), source=path)
        line = table_mismatch(tab, cal, path, cal_path)
        if line:
            print(f"playscope: warning: {line}", file=sys.stderr)
    from .sim.plant import session_plant  # the simulator stays behind the plant interface

    plant, plant_note = session_plant(s)
    ev = evaluate(cal, s, table=tab, plant=plant, plant_note=plant_note, comp_duration_s=comp_duration_s,
                  source=os.fspath(session_dir))
    ev.summary["calibration"] = os.fspath(cal_path)
    if table_path:
        ev.summary["table"] = os.fspath(table_path)
    return Evaluated(ev, cal)


@dataclass
class Reported:
    """write_report_file's result: the HTML file, its size and the figures in it."""

    path: str  # as given
    bytes: int
    figures: list = field(default_factory=lambda: ["characteristic", "backlash", "prediction", "compensation"])

    def line(self) -> str:
        return f"{self.path}: {self.bytes} bytes, 4 figures"

    def to_json(self) -> dict:
        return {"report": self.path, "figures": self.figures, "bytes": self.bytes}


def write_report_file(cal_path, session_dir, out, eval_json=None) -> Reported:
    """Single-file HTML report (report.write_report) of the calibration on the session; the
    tables come from eval_json (an `evaluate --json` file) when given, else are computed here.
    The figures are always computed from the inputs."""
    import json

    from .evaluate.prediction import format_table
    from .evaluate.html_report import write_report

    done = evaluate_session(session_dir, cal_path)
    ev, summary = done.evaluation, done.summary
    if eval_json:
        path = Path(eval_json)
        if not path.is_file():
            raise InputError(path, "file not found")
        try:
            summary = json.loads(path.read_text())
            md = format_table(summary)
        except (json.JSONDecodeError, KeyError, TypeError) as e:
            raise InputError(path, f"not an `evaluate --json` file: {e}") from None
    else:
        md = format_table(summary)
    write_report(out, done.cal, ev, md)
    return Reported(os.fspath(out), Path(out).stat().st_size)



# --------------------------------------------------------------------------- run-insitu
@dataclass
class InsituSource:
    """Where run_insitu's frames come from: a simulated instrument rendered from the board's
    encoder stream (sim_plant, with its seed, board time_scale and excitation exc) or a video
    file / camera index with the geometry file (session.json: robot, camera, hand-eye). exc, the
    excitation Q0:Q1:AMP:ADV:V, is sent to the board (PSP_MSG_EXC_CONFIG) on every image; with
    pace the board paces it itself (its exc_pace_config, the same speed as fit.pacing)."""

    video: str | int | None = None
    geometry: str | None = None
    sim_plant: bool = False
    seed: int = 1
    time_scale: float = 1.0
    exc: str | None = None
    pace: tuple | None = None    # (b_low, b_high, fps) when exc's speed was paced to the camera


@dataclass
class InsituRan:
    """run_insitu's result: board and wall time (s), frames, B samples (all and valid), the
    calibrated q range, the flash result (board.flash.flash's dict, None without flashing) and,
    for a simulated instrument, |B_fit - B_true| (mm: mean, max, and over the samples)."""

    ended: str
    board_s: float
    wall_s: float
    frames: int
    b_samples: int
    b_valid: int
    q_range: list
    flash: dict | None = None
    excitation: dict | None = None
    sim_B_err_mm: dict | None = None
    sim_grid: tuple = ()

    def line(self) -> str:
        return (f"{self.ended}: {self.board_s:.1f} s board time in {self.wall_s:.1f} s, {self.frames} frames, "
                f"{self.b_samples} B samples from the board ({self.b_valid} valid)")

    def sim_line(self) -> str | None:
        e = self.sim_B_err_mm
        if not e:
            return None
        return (f"SIMULATION truth: |B_fit - B_true| mean {e['mean']:.3f} mm, max {e['max']:.3f} mm over "
                f"q in [{self.sim_grid[0]:.2f}, {self.sim_grid[1]:.2f}]; board samples mean {e['samples_mean']:.3f} mm")

    def to_json(self) -> dict:
        d = {"board_s": self.board_s, "wall_s": self.wall_s, "frames": self.frames, "b_samples": self.b_samples,
             "b_valid": self.b_valid, "q_range": list(self.q_range)}
        if self.sim_B_err_mm is not None:
            d["sim_B_err_mm"] = self.sim_B_err_mm
        if self.flash is not None:
            d["flash"] = self.flash
        if self.excitation is not None:
            d["excitation"] = self.excitation
        return d


def run_insitu(link, src: InsituSource, seconds=None, n_ctrl: int = 14, out=None, flash_after: bool = True,
               n_vectors: int = 200, progress=None, ran=None) -> InsituRan:
    """The paper's in-situ procedure (section III) on the board behind link (board.insitu_run):
    the board's excitation and onset detector run while frames come from src; the host fits
    B(q), f_remain and the transition to the board's samples, builds the Q16.16 table and
    flashes it (flash_after). out: folder for b_samples.csv, session/, calibration.json,
    table.bin and result.json (None: nothing written). progress(board_s, n_samples, total_s or
    None) follows the run; ran(line) is called once the run ends, with InsituRan.line().
    Errors: OSError for a video that cannot be opened, InputError when the fit refuses the
    run, RuntimeError for a failed flash (nothing of out is lost)."""
    import json

    from .base.atomic import write_bytes_atomic
    from .base.jsonio import write_json
    from .board.flash import flash
    from .board.insitu_run import (VideoSource, calibrate_run, exc_duration_s, read_geometry, run_loop,
                                   session_of, write_samples_csv)
    from .fit.table_build import build_table
    from .io.session import write_session

    out = Path(out) if out else None
    if out:
        out.mkdir(parents=True, exist_ok=True)
    plant = None
    if src.sim_plant:
        from .sim.plant import SimPlant, SimPlantConfig

        plant = SimPlant(SimPlantConfig(seed=src.seed, time_scale=src.time_scale, exc=src.exc))
        source = plant
        sim = plant.sim
        robot, camera, hand_eye, t_delay = sim.robot(), sim.camera(), sim.hand_eye(), sim.t_delay_s
        total = exc_duration_s(src.exc)
    else:
        robot, camera, hand_eye, t_delay = read_geometry(src.geometry)
        source = VideoSource(src.video)
        total = None
    board_exc = None
    if src.exc:  # the excitation reaches the board whatever its image (virtual, UART, USB)
        link.set_mode("idle")
        if src.pace:
            board_exc = link.exc_config(":".join(src.exc.split(":")[:4]), *src.pace)
        else:
            board_exc = link.exc_config(src.exc)
        board_exc["exc"] = src.exc
    try:
        run = run_loop(link, source, seconds,
                       progress=(lambda s, n: progress(s, n, total)) if progress else None)
    finally:
        if not plant:
            source.close()
    valid = run.valid()
    res = InsituRan(run.ended, run.board_s, run.wall_s, len(run.mk_t_s), len(run.samples), len(valid), [],
                    excitation=board_exc)
    if ran:
        ran(res.line())
    s = session_of(run, robot, camera, hand_eye, t_delay)
    if out:
        write_samples_csv(out / "b_samples.csv", run.samples)
        write_session(s, out / "session", overwrite=True)  # guarded: an existing one needs --force
    cal = calibrate_run(run, s, n_ctrl)
    q_min, q_max = cal.q_range
    res.q_range = [q_min, q_max]
    tab = build_table(cal.B_model, cal.f, q_min, q_max, "mm", "remain", 1, transition=cal.transition)
    if plant:
        g = np.linspace(q_min + 0.3, q_max - 0.3, 101)
        e = np.abs(cal.B(g) - plant.truth_B(g))
        qm = np.array([x["q_mean"] for x in valid])
        eb = np.abs(np.array([x["b"] for x in valid]) - plant.truth_B(qm)) if valid else np.zeros(1)
        res.sim_B_err_mm = {"mean": float(e.mean()), "max": float(e.max()),
                            "samples_mean": float(eb.mean()), "samples_max": float(eb.max())}
        res.sim_grid = (float(g[0]), float(g[-1]))
    if out:
        cal.save(out / "calibration.json")
        write_bytes_atomic(out / "table.bin", tab.blob)
    if flash_after:
        try:
            res.flash = flash(link, tab.blob, n_vectors)
        except (RuntimeError, ValueError) as e:
            raise RuntimeError(f"flash failed: {e}") from None
    if out:
        write_json(out / "result.json", res.to_json(), indent=1)
    return res


# --------------------------------------------------------------------------- import
@dataclass
class Imported:
    """import_recording's result: the session folder written, its encoder rows and time span
    (s), what the reader reported (notes: CSV repairs, or a bag's per-stream lines) and whether
    the source was a ROS bag."""

    session: str
    rows: int
    t_span_s: float
    notes: list
    bag: bool

    def line(self) -> str:
        return f"{self.session}: {self.rows} rows, {self.t_span_s:.1f} s"

    def to_json(self) -> dict:
        return {"session": self.session, "rows": self.rows, "t_span_s": self.t_span_s, "streams": list(self.notes)}


def import_recording(source, out, csv: dict | None = None, bag: dict | None = None, q_source: str | None = None,
                     overwrite: bool = False, progress=None) -> Imported:
    """A foreign recording -> a session folder at out. csv: importer.import_csv's keyword
    arguments (t_col, q_col, c_col, time_scale, q_scale, unit, q_per_rad, c_scale, t_delay_s,
    q_source) for a CSV (progress: a tqdm-like factory for the reading's bar); bag: rosbag.import_bag's (q, c, image: the topics; geometry, unit,
    q_scale, c_scale, q_per_rad, t_delay_s) for a ROS bag (q_source set on the session after).
    Errors: InputError naming the file and row; ValueError for a bag the reader refuses."""
    if bag is not None:
        from .io.rosbag import import_bag, write_bag_session

        s, report, frames = import_bag(source, **bag)
        s.q_source = q_source
        notes = report.lines()
        write_bag_session(s, frames, out, overwrite=overwrite)
    else:
        from .io.importer import import_csv
        from .io.session import write_session

        s = import_csv(source, **(csv or {}), progress=progress)
        notes = list(s.notes)
        write_session(s, out, overwrite=overwrite)
    t = s.encoder["t_s"]
    return Imported(str(out), int(t.size), float(t[-1] - t[0]), notes, bag is not None)


# --------------------------------------------------------------------------- evaluate-insitu
@dataclass
class InsituEvaluated:
    """evaluate_insitu_record's result: the document of evaluate.insitu_split.evaluate_insitu
    (its JSON_KEYS) and what loading repaired in the record (warnings)."""

    doc: dict
    warnings: list = field(default_factory=list)

    def text(self) -> str:
        from .evaluate.insitu_split import format_insitu

        return format_insitu(self.doc)

    def to_json(self) -> dict:
        return self.doc


def evaluate_insitu_record(path, split: float | str = 0.5, progress=None, loaded=None) -> InsituEvaluated:
    """Every model fitted before the split of one record and scored after it
    (evaluate.insitu_split). path: a session folder or a recording file (importer.load_recording);
    loaded: the Session already read from path (its notes are the warnings)."""
    from .evaluate.insitu_split import evaluate_insitu
    from .io.importer import load_recording

    s = loaded if loaded is not None else load_recording(path)
    kw = {"progress": progress} if progress else {}
    return InsituEvaluated(evaluate_insitu(s, split, source=path, **kw), list(s.notes))


# --------------------------------------------------------------------------- evaluate-real
@dataclass
class RealEvaluated:
    """evaluate_real_data's result: the document (evaluate.real_eval's tables, or board.online's
    on-line update tables) and its Markdown text."""

    doc: dict
    text: str

    def to_json(self) -> dict:
        return self.doc


def evaluate_real_data(folder, reimage=None, online: bool = False, progress=None) -> RealEvaluated:
    """The acceptance tables on the catheter recordings in folder: in situ and across sessions
    (evaluate.real_eval), through a re-imaging work folder (reimage), or the on-line update
    protocol (online; board.online)."""
    kw = {"progress": progress} if progress else {}
    if online:
        from .board.online import evaluate_real_online, format_online

        res = evaluate_real_online(folder, **kw)
        return RealEvaluated(res, format_online(res))
    from .evaluate.real_eval import evaluate_real, evaluate_real_reimaged, format_tables

    res = evaluate_real_reimaged(folder, reimage, **kw) if reimage else evaluate_real(folder, **kw)
    return RealEvaluated(res, format_tables(res))


# --------------------------------------------------------------------------- evaluate-transfer
@dataclass
class Transferred:
    """transfer_records' result: evaluate.transfer's document, its Markdown table, and the plot
    written (or None)."""

    doc: dict
    text: str
    plot: str | None = None

    def to_json(self) -> dict:
        return self.doc


def transfer_records(cal, records, warmup: float, refresh_s: float, plot=None, progress=None) -> Transferred:
    """A calibration made on the record cal run on each of records (evaluate.transfer), with and
    without each on-line update; plot: PNG of RMSE against the configuration angle."""
    from .evaluate.transfer import evaluate_transfer, format_transfer, plot_transfer

    kw = {"progress": progress} if progress else {}
    doc = evaluate_transfer(cal, records, warmup, refresh_s, **kw)
    if plot:
        plot_transfer(doc, plot)
    return Transferred(doc, format_transfer(doc), os.fspath(plot) if plot else None)


# --------------------------------------------------------------------------- diagnose
@dataclass
class Diagnosed:
    """diagnose_records' result: per record name, the diagnosis document (diagnose.run.clean)
    and its summary lines (diagnose.run.summary_lines); warnings: what loading repaired; html:
    the page written, or None."""

    records: dict
    lines: dict
    warnings: list = field(default_factory=list)
    html: str | None = None

    def to_json(self) -> dict:
        return {"sessions": self.records}


def diagnose_records(records, split: float, test=None, html=None) -> Diagnosed:
    """The sim-to-real gap diagnosis (diagnose.run.diagnose_data) of each record: records is a
    list of (name, path, kind) with kind "session" (a session folder or recording file,
    importer.load_recording) or "catheter" (importer.import_catheter); test: one (path, kind)
    scored as a separate test record; html: write the diagnosis page there."""
    from .diagnose.fitmodel import from_session
    from .diagnose.run import clean, diagnose_data, summary_lines
    from .io.importer import import_catheter, load_recording

    def load(path, kind):
        return import_catheter(path) if kind == "catheter" else load_recording(path)

    test_data = from_session(load(*test)) if test else None
    out, lines, warnings, figs_all = {}, {}, [], []
    for name, path, kind in records:
        session = load(path, kind)
        warnings += list(session.notes) if kind == "session" else []
        data = from_session(session)
        res = diagnose_data(data, split, session=session, test_data=test_data)
        data = res.pop("_data")
        lines[name] = summary_lines(name, res)
        if html:
            from .diagnose.diagnosis_report import figures

            figs_all += [(f"{name}: {t}", img) for t, img in figures(data, res, res["atlas_before"], res["atlas_after"])]
        res.pop("_models", None)
        out[name] = clean(res)
    if html:
        from .base.atomic import write_text_atomic
        from .diagnose.diagnosis_report import html_page

        write_text_atomic(html, html_page("playscope diagnose", out, figs_all))
    return Diagnosed(out, lines, warnings, os.fspath(html) if html else None)
