"""Protocol client: numbered requests over a transport, through the C codec; table flashing and checks."""

from __future__ import annotations

import collections
import time

from ..base.native import enum_names, frame_codec
from .transport import Transport, TransportError


def error_name(code: int) -> str:
    """Name of a psp_error_code (common/ps_proto.h), e.g. 8 -> "TABLE"."""
    return {0: "OK", **enum_names("enum psp_error_code", "PSP_ERR_", lower=False)}.get(code, str(code))


def mode_names() -> dict[int, str]:
    """{value: name} of enum psp_mode (common/ps_proto.h): 0 -> "idle", ..."""
    return enum_names("enum psp_mode", "PSP_MODE_")


def table_refusal(detail: int) -> str:
    """What psp_error_t.detail of a TABLE refusal means: a calib_status_t (its name and the
    loader's reason, read from the C), or the link's own PSL_DETAIL_GENERATION."""
    ffi, lib = frame_codec()
    if detail == 0x80:  # PSL_DETAIL_GENERATION (firmware/link/psl_link.h, not in the host's headers)
        return ("generation not the next one (1..PST_GENERATION_STEP_MAX above the running table's); a board at "
                "generation 0xFFFFFFFF takes no table until recovered by its physical path (docs/robustness.md)")
    name = enum_names("calib_status_t", "", lower=False).get(detail)
    return f"{name}: {ffi.string(lib.calib_status_str(detail)).decode()}" if name else f"detail {detail}"


class DeviceError(RuntimeError):
    """The board refused a request (PSP_MSG_ERROR); code/detail as in ps_proto.h."""

    def __init__(self, code: int, ref_type: int, detail: int):
        self.code, self.ref_type, self.detail = code, ref_type, detail
        if self.busy:
            msg = (f"board busy: another host is uploading a table (its session ends when it commits or "
                   f"aborts, or after {detail} s without a request); try again then")
        else:
            msg = f"board refused request 0x{ref_type:02x}: {error_name(code)} (detail {detail})"
            if error_name(code) == "TABLE":
                msg += f": {table_refusal(detail)}"
        super().__init__(msg)

    @property
    def busy(self) -> bool:
        """PSP_ERR_BUSY: another host holds the board's upload session."""
        return error_name(self.code) == "BUSY"


def _struct_bytes(ffi, ctype: str, **fields) -> bytes:
    p = ffi.new(f"{ctype} *")
    for k, v in fields.items():
        setattr(p, k, v)
    return bytes(ffi.buffer(p))


class Link:
    """One host session with a board. Requests carry seq numbers above the board's last
    accepted one (learnt from INFO, which is exempt from the replay check); seq 0 is
    reserved for unsolicited board frames, which are queued in ``events``."""

    def __init__(self, transport: Transport, timeout_s: float = 3.0):
        self.t = transport
        self.timeout_s = timeout_s
        self.ffi, self.lib = frame_codec()
        self.parser = self.ffi.new("psf_parser_t *")
        self.lib.psf_parser_reset(self.parser)
        self.res = self.ffi.new("psf_result_t *")
        self.out = self.ffi.new("uint8_t[]", self.lib.PSF_MAX_FRAME)
        self.seq = 0
        self.pending = collections.deque()   # frames decoded but not yet claimed
        self.events = collections.deque()    # unsolicited (seq 0) frames
        self.n_requests = 0
        self.sync()

    # ---------------------------------------------------------------- framing
    def encode(self, mtype: int, seq: int, payload: bytes = b"") -> bytes:
        n = self.lib.psf_encode(self.out, self.lib.PSF_MAX_FRAME, mtype, seq, payload, len(payload))
        if n == 0:
            raise ValueError(f"payload of {len(payload)} bytes exceeds PSP_MAX_PAYLOAD")
        return bytes(self.ffi.buffer(self.out, n))

    def _feed(self, data: bytes) -> None:
        buf = self.ffi.from_buffer(data)
        off = 0
        while off < len(data) or self.parser.have > 0:
            used = self.lib.psf_parser_push(self.parser, buf + off, len(data) - off, self.res)
            off += used
            r = self.res[0]
            if r == self.lib.PSF_FRAME:
                h = self.parser.hdr
                pl = bytes(self.ffi.buffer(self.lib.psf_parser_payload(self.parser), h.len))
                frame = (h.type, h.seq, pl)
                (self.events if h.seq == 0 and h.type != self.lib.PSP_MSG_ERROR else self.pending).append(frame)
            elif r == self.lib.PSF_NEED_MORE and used == 0:
                break

    def _wait(self, seq: int, timeout_s: float):
        deadline = time.monotonic() + timeout_s
        while True:
            for i, f in enumerate(self.pending):
                if f[1] == seq:
                    del self.pending[i]
                    return f
            left = deadline - time.monotonic()
            if left <= 0:
                raise TransportError(f"{self.t.name}: no answer to request seq {seq} within {timeout_s} s")
            self._feed(self.t.read(left))

    def request(self, mtype: int, payload: bytes = b"", *, seq: int | None = None,
                timeout_s: float | None = None) -> bytes:
        """Send one request and return the answer payload. Errors: DeviceError, TransportError."""
        if seq is None:
            self.seq = (self.seq + 1) & 0xFFFF or 1
            seq = self.seq
        self.t.write(self.encode(mtype, seq, payload))
        self.n_requests += 1
        rtype, _, pl = self._wait(seq, timeout_s or self.timeout_s)
        if rtype == self.lib.PSP_MSG_ERROR:
            e = self.ffi.from_buffer("psp_error_t *", pl)
            raise DeviceError(e.code, e.ref_type, e.detail)
        if rtype != (mtype | self.lib.PSP_RESPONSE):
            raise TransportError(f"answer type 0x{rtype:02x} to request 0x{mtype:02x}")
        return pl

    # ---------------------------------------------------------------- requests
    def _info_from(self, pl: bytes) -> dict:
        i = self.ffi.from_buffer("psp_info_t *", pl)
        v = i.fw_version
        return {"fw_version": f"{v >> 16}.{(v >> 8) & 0xFF}.{v & 0xFF}", "proto_version": i.proto_version,
                "table_layout_version": i.table_layout_version,
                "board_id": "-".join(f"{i.board_id[k]:08x}" for k in range(3)),
                "active_generation": i.active_generation, "active_crc32": i.active_crc32,
                "mode": mode_names().get(i.mode, str(i.mode)),
                "active_slot": {0: "A", 1: "B"}.get(i.active_slot, "none"), "last_seq": i.last_seq}

    def board_limits(self):
        """PSP_MSG_BOARD: the board's own limits (a cffi ``pst_limits_t *``: instrument id, unit,
        travel, angle range, largest play), or None for a board whose firmware predates the
        request (answered TYPE). Read-only, answered whatever its seq, like INFO."""
        s = (self.seq + 1) & 0xFFFF or 1
        try:
            pl = self.request(self.lib.PSP_MSG_BOARD, seq=s)
        except DeviceError as e:
            if error_name(e.code) == "TYPE":
                return None
            raise
        lim = self.ffi.new("pst_limits_t *")
        self.ffi.memmove(lim, pl, min(len(pl), self.ffi.sizeof("pst_limits_t")))
        return lim

    def limits_info(self) -> dict:
        """board_limits() as printable fields ({} for a board without the request): instrument,
        unit, travel and angle range ("[lo, hi]", actuator units and deg), largest play."""
        lim = self.board_limits()
        if lim is None:
            return {}
        one = float(self.lib.PS_Q16_ONE)
        unit = {self.lib.PST_Q_UNIT_MM: "mm", self.lib.PST_Q_UNIT_DEG: "deg"}.get(lim.q_unit, str(lim.q_unit))
        return {"instrument": int(lim.instrument_id), "unit": unit,
                "travel": f"[{lim.q_min_q16 / one:g}, {lim.q_max_q16 / one:g}] {unit}",
                "angle_range_deg": f"[{lim.c_min_q16 / one:g}, {lim.c_max_q16 / one:g}]",
                "b_max": f"{lim.b_max_q16 / one:g} {unit}"}

    def info(self) -> dict:
        # INFO is answered whatever its seq; use the next one so answers stay distinct.
        s = (self.seq + 1) & 0xFFFF or 1
        return self._info_from(self.request(self.lib.PSP_MSG_INFO, seq=s))

    def sync(self, attempts: int = 10) -> dict:
        """Read INFO and continue numbering above the board's last accepted request.
        Retried because a board just powered up (or QEMU just started) may drop the
        first bytes before its UART is enabled."""
        self.seq = 0
        for k in range(attempts):
            self.pending.clear()
            self.lib.psf_parser_reset(self.parser)
            try:
                info = self._info_from(self.request(self.lib.PSP_MSG_INFO, seq=0xFFFF,
                                                    timeout_s=min(self.timeout_s, 0.5)))
                break
            except TransportError:
                if k == attempts - 1:
                    raise
                self.t.write(b"\0" * 16)  # flush a half-received frame on the board
        self.seq = info["last_seq"]
        return info

    def set_mode(self, mode: str | int) -> None:
        m = mode if isinstance(mode, int) else {v: k for k, v in mode_names().items()}[mode]
        self.request(self.lib.PSP_MSG_SET_MODE, _struct_bytes(self.ffi, "psp_set_mode_t", mode=m))

    def begin_upload(self, size: int, crc32: int) -> int:
        """TABLE_BEGIN: open the board's upload session; returns its token. Errors:
        DeviceError (BUSY while another host holds a session, RANGE for a bad size)."""
        pl = self.request(self.lib.PSP_MSG_TABLE_BEGIN,
                          _struct_bytes(self.ffi, "psp_table_begin_t", total_size=size, crc32=crc32))
        return self.ffi.from_buffer("psp_table_session_t *", pl).session

    def abort_upload(self, session: int) -> None:
        """TABLE_ABORT: give the session up (the board is free for another host at once)."""
        self.request(self.lib.PSP_MSG_TABLE_ABORT, _struct_bytes(self.ffi, "psp_table_abort_t", session=session))

    def upload_table(self, blob: bytes, progress=None) -> dict:
        """BEGIN (one owner per upload: the board's session token), CHUNKs, COMMIT. Returns
        the board's INFO after the commit. A failure after BEGIN aborts the session so the
        board is free again; errors: DeviceError, TransportError."""
        ffi, lib = self.ffi, self.lib
        crc = int.from_bytes(blob[12:16], "little")
        session = self.begin_upload(len(blob), crc)
        hdr_len = ffi.offsetof("psp_table_chunk_t", "data")
        try:
            for off in range(0, len(blob), lib.PSP_CHUNK_MAX):
                data = blob[off:off + lib.PSP_CHUNK_MAX]
                c = ffi.new("psp_table_chunk_t *")
                c.offset, c.len, c.session = off, len(data), session
                c.chunk_crc32 = lib.ps_crc32_update(0, data, len(data))
                ffi.memmove(c.data, data, len(data))
                self.request(lib.PSP_MSG_TABLE_CHUNK, bytes(ffi.buffer(c, hdr_len + len(data))))
                if progress:
                    progress(off + len(data), len(blob))
            pl = self.request(lib.PSP_MSG_TABLE_COMMIT,
                              _struct_bytes(ffi, "psp_table_commit_t", crc32=crc, session=session),
                              timeout_s=max(self.timeout_s, 10.0))  # a sector erase takes ~1-2 s on the F405
        except (DeviceError, TransportError):
            try:  # a refused commit already closed it; an interrupted upload still holds it
                self.abort_upload(session)
            except (DeviceError, TransportError):
                pass
            raise
        return self._info_from(pl)

    def read_table(self) -> bytes:
        """The board's active table, read back in PSP_CHUNK_MAX chunks, each checked by its CRC32 and
        offset. Errors: TransportError on a chunk that fails them, and what `request` raises."""
        ffi, lib = self.ffi, self.lib
        out = bytearray()
        while True:
            pl = self.request(lib.PSP_MSG_TABLE_READ,
                              _struct_bytes(ffi, "psp_table_read_t", offset=len(out), len=lib.PSP_CHUNK_MAX))
            c = ffi.new("psp_table_chunk_t *")
            ffi.memmove(c, pl, len(pl))
            data = bytes(ffi.buffer(c.data, c.len))
            if lib.ps_crc32_update(0, data, len(data)) != c.chunk_crc32 or c.offset != len(out):
                raise TransportError("read-back chunk failed its CRC or offset check")
            if c.len == 0:
                return bytes(out)
            out += data

    def comp_step(self, c_ref_q16: int) -> int:
        pl = self.request(self.lib.PSP_MSG_COMP_STEP, _struct_bytes(self.ffi, "psp_comp_req_t", c_ref_q16=c_ref_q16))
        return self.ffi.from_buffer("psp_comp_resp_t *", pl).q_ref_q16

    def stream(self, enable: bool, decimation: int = 1) -> None:
        self.request(self.lib.PSP_MSG_ENC_STREAM,
                     _struct_bytes(self.ffi, "psp_stream_ctl_t", enable=int(enable), decimation=decimation))

    def _b_sample(self, pl: bytes) -> dict | None:
        if len(pl) != self.ffi.sizeof("psp_b_sample_t"):
            return None
        b = self.ffi.from_buffer("psp_b_sample_t *", pl)
        return {k: getattr(b, k) for k in ("reason", "t1_us", "t2_us", "q1_q16", "q2_q16", "q_mean_q16", "b_q16")}

    def reversal(self, t1_us: int, q1_q16: int) -> dict | None:
        return self._b_sample(self.request(self.lib.PSP_MSG_REVERSAL,
                                           _struct_bytes(self.ffi, "psp_reversal_t", t1_us=t1_us, q1_q16=q1_q16)))

    def marker(self, t_us: int, u_q16: int, v_q16: int, valid: bool = True, kind: int = 0) -> dict | None:
        pl = _struct_bytes(self.ffi, "psp_marker_obs_t", t_us=t_us & 0xFFFFFFFF, u_q16=u_q16, v_q16=v_q16,
                           valid=int(valid), kind=kind)
        return self._b_sample(self.request(self.lib.PSP_MSG_MARKER_OBS, pl))

    def learn(self, op: str = "query") -> dict:
        """On-line B update on the board (PSP_MSG_LEARN, docs/online.md): op "start" (on the
        running table's B), "stop" (back to the flashed B) or "query". Returns the board's
        psp_learn_state_t as a dict: samples learnt, queued, dropped, b_crc32 (CRC-32 of the B
        entries it runs), n_grid, n_nodes, on. Errors: BoardError STATE when starting without
        a table."""
        ops = {"query": self.lib.PSP_LEARN_QUERY, "start": self.lib.PSP_LEARN_START, "stop": self.lib.PSP_LEARN_STOP}
        pl = self.request(self.lib.PSP_MSG_LEARN, _struct_bytes(self.ffi, "psp_learn_ctl_t", op=ops[op]))
        st = self.ffi.from_buffer("psp_learn_state_t *", pl)
        return {k: int(getattr(st, k)) for k in ("samples", "queued", "dropped", "b_crc32", "n_grid", "n_nodes", "on")}

    def exc_config(self, exc: str, b_low: float | None = None, b_high: float | None = None,
                   fps: float | None = None) -> dict:
        """Set the excitation the board runs next (PSP_MSG_EXC_CONFIG), on any image. exc
        "Q0:Q1:AMP:ADV:V" (actuator units, V units/s) runs at V; "Q0:Q1:AMP:ADV" is paced to the
        camera by the board itself (exc_pace_config: b_low taken up over EXC_PACE_FRAMES frames),
        which needs the expected play b_low, b_high (units) and the camera's fps (also the onset
        detector's frame period). Q values as the board holds them (truncated to Q16, as
        fit.pacing.paced_exc). Returns what the board will run: {"v_q32", "v" (units/s),
        "frame_period_us"}. Errors: ValueError for a malformed exc or a missing play range or
        frame rate; DeviceError RANGE (detail: exc_status_t) for a config the board refuses,
        STATE during an excitation."""
        from ..base import native
        from ..fit.pacing import TICK_HZ, _play_q16, frame_period_us

        parts = exc.split(":")
        try:
            vals = [float(x) for x in parts]
        except ValueError:
            vals = []
        if len(vals) not in (4, 5):
            raise ValueError(f"excitation {exc!r} is not Q0:Q1:AMP:ADV[:V] (4 or 5 numbers separated by ':')")
        q16 = [int(x * native.Q16_ONE) for x in vals[:4]]
        f = dict(q_start_q16=q16[0], q_end_q16=q16[1], amplitude_q16=q16[2], advance_q16=q16[3], return_sweep=1,
                 frame_period_us=frame_period_us(fps) if fps is not None else 0)
        if len(vals) == 5:
            f["v_q32"] = int(vals[4] / TICK_HZ * 2.0**32)
            if f["v_q32"] <= 0:
                raise ValueError(f"excitation {exc!r}: the speed V must be > 0")
        else:
            if b_low is None or b_high is None or fps is None:
                raise ValueError(f"excitation {exc!r} without a speed is paced to the camera: it needs the "
                                 f"expected play range and the frame rate")
            f.update(v_q32=0, b_low_q16=_play_q16("b_low", b_low), b_high_q16=_play_q16("b_high", b_high))
        pl = self.request(self.lib.PSP_MSG_EXC_CONFIG, _struct_bytes(self.ffi, "psp_exc_config_t", **f))
        a = self.ffi.from_buffer("psp_exc_config_t *", pl)
        return {"v_q32": int(a.v_q32), "v": int(a.v_q32) * TICK_HZ / 2.0**32, "frame_period_us": int(a.frame_period_us)}

    def poll_events(self, timeout_s: float = 0.0) -> list:
        """Drain unsolicited frames: ('b', dict) for B samples, ('enc', [(t_us, q_q16)...])."""
        if timeout_s > 0:
            self._feed(self.t.read(timeout_s))
        out = []
        while self.events:
            mtype, _, pl = self.events.popleft()
            if mtype == (self.lib.PSP_MSG_MARKER_OBS | self.lib.PSP_RESPONSE):
                out.append(("b", self._b_sample(pl)))
            elif mtype == (self.lib.PSP_MSG_ENC_STREAM | self.lib.PSP_RESPONSE):
                e = self.ffi.new("psp_enc_samples_t *")
                self.ffi.memmove(e, pl, len(pl))
                out.append(("enc", [(e.s[k].t_us, e.s[k].q_q16) for k in range(e.count)]))
        return out

    def close(self) -> None:
        self.t.close()
