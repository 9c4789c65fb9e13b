"""End to end in CI: a simulated session -> `playscope calibrate` -> `playscope tables`
-> flashed to the virtual board over the emulated USB device (ps_usbemu, the host's unmodified
pyusb/libusb) AND to the STM32F405 link firmware under QEMU over USART1 -> read back identical
-> the boards' compensator outputs equal the host's run of the same C code, bit for bit.

The session comes from the simulator (playscope.sim, preset "ideal": the paper's model without
extra effects), 40 s of excitation at 500 Hz with a 25 Hz marker camera, so the whole test
stays well under a minute (about 10 s here, QEMU included).
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from playscope.cli import main
from playscope.board.flash import flash
from playscope.board.link import Link
from playscope.fit import table_build as T
from playscope.board.transport import QemuTransport, find_qemu_image
from playscope.io.session import write_session

from .test_usb_umockdev import CLIENT, _emu_or_skip

N_VECTORS = 300


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """(table blob path, simulator config, calibration JSON) from a fresh simulated session."""
    from playscope.sim.core import preset, simulate

    d = tmp_path_factory.mktemp("e2e")
    cfg = preset("ideal", seed=4, trajectory={"kind": "excitation", "q_lo": -3.0, "q_hi": 3.0,
                                              "amp": 1.4, "speed": 0.8, "duration_s": 40.0})
    write_session(simulate(cfg), d / "session")
    assert main(["calibrate", str(d / "session"), "-o", str(d / "cal.json")]) == 0
    assert main(["tables", str(d / "cal.json"), "-o", str(d / "table.bin")]) == 0
    return d / "table.bin", cfg, json.loads((d / "cal.json").read_text())


def test_calibration_is_sane(calibrated):
    """The table under test encodes a calibration close to the simulated truth (else a
    bit-exact flash of a wrong table would prove little)."""
    from playscope.fit.calibration import Calibration

    path, cfg, _ = calibrated
    cal = Calibration.load(path.with_name("cal.json"))
    g = np.linspace(-2.5, 2.5, 51)
    assert np.max(np.abs(cal.B(g) - cfg.B_fn()(g))) < 0.05  # mm


def _host_run(blob: bytes) -> tuple[bytes, list[int]]:
    """What the boards must hold after a first flash (generation 1) and answer to test_vector."""
    sent = T.set_generation(blob, 1)
    host = T.CalibTable(sent)
    c = T.test_vector(host, N_VECTORS)
    return sent, host.comp_run(c)


def test_usb_emulated_virtual_board(calibrated, tmp_path):
    usbemu = _emu_or_skip()
    path, _, _ = calibrated
    r = usbemu.run([sys.executable, str(CLIENT), "flash", str(path), str(N_VECTORS)],
                   flash_file=tmp_path / "flash.bin")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    sent, q_host = _host_run(path.read_bytes())
    assert out["flash"]["generation"] == 1
    assert bytes.fromhex(out["readback_hex"]) == sent
    assert out["comp_steps"] == N_VECTORS and out["comp_mismatches"] == 0
    assert out["q_board"] == q_host
    # The q* sequence moves (not a constant that would match trivially).
    assert len(set(q_host)) > N_VECTORS // 2


@pytest.mark.skipif(shutil.which("qemu-system-arm") is None or find_qemu_image() is None,
                    reason="needs qemu-system-arm and the playscope-link-fw image (stm32f405 preset)")
def _qemu_flash_and_compensate(blob: bytes, sent: bytes) -> list[int]:
    """Flash blob to the STM32F405 link firmware under QEMU, check the read-back equals sent,
    and return the board's compensator outputs on the host's test vector."""
    link = Link(QemuTransport())
    try:
        r = flash(link, blob, N_VECTORS, log=lambda *_: None)
        assert r["generation"] == 1
        assert link.read_table() == sent
        c = T.test_vector(T.CalibTable(sent), N_VECTORS)
        link.set_mode("compensation")
        q_board = [link.comp_step(x) for x in c]
        link.set_mode("idle")
    finally:
        link.close()
    return q_board


def test_qemu_firmware_over_serial(calibrated):
    path, _, _ = calibrated
    sent, q_host = _host_run(path.read_bytes())
    assert _qemu_flash_and_compensate(path.read_bytes(), sent) == q_host


def test_cli_flash_virtual(calibrated, capsys):
    """`playscope flash TABLE --device virtual`: the CLI path itself on the same table."""
    path, _, _ = calibrated
    assert main(["flash", str(path), "--device", "virtual", "--vectors", "100"]) == 0
    out = capsys.readouterr().out
    assert "read back identical" in out and "bit-identical" in out


def test_qemu_runs_a_layout_3_table_bit_for_bit(tmp_path):
    """A table with the threshold map (layout 3: B-proportional thresholds, g and g^-1 on the
    board) flashed to the STM32F405 link firmware under QEMU: read back identical, and the
    board's compensator (f^-1, PI^-1, g^-1, B/2) equals the host's run of the same C."""
    from playscope.fit.transition import ThresholdMap, Transition, thresholds

    B = lambda q: 0.3 + 0.03 * (np.asarray(q, float) + 5.0)  # 0.3 .. 0.6 mm over the travel
    f = lambda q: 3.0 * np.asarray(q, float) + 0.04 * np.asarray(q, float) ** 2
    tr = Transition(thresholds(8, 0.8), np.r_[0.4, np.full(7, 0.6 / 7)], 1.0,
                    ThresholdMap.from_backlash(B, -5.3, 5.3))
    blob = T.build_table(B, f, -5.0, 5.0, "mm", transition=tr).blob
    assert T.header(blob).layout_version == 5 and T.CalibTable(blob).has_map
    sent, q_host = _host_run(blob)
    assert _qemu_flash_and_compensate(blob, sent) == q_host


def test_qemu_runs_a_layout_4_table_bit_for_bit(tmp_path):
    """A table with the travel-domain relaxation (layout 4: R^-1 on the board before PI^-1, with
    the threshold map) flashed to the STM32F405 link firmware under QEMU: read back identical,
    and the board's compensator equals the host's run of the same C, bit for bit."""
    from playscope.fit.relax import Relaxation
    from playscope.fit.transition import ThresholdMap, Transition, thresholds

    B = lambda q: 0.3 + 0.03 * (np.asarray(q, float) + 5.0)
    f = lambda q: 3.0 * np.asarray(q, float) + 0.04 * np.asarray(q, float) ** 2
    tr = Transition(thresholds(8, 0.8), np.r_[0.4, np.full(7, 0.6 / 7)], 1.0,
                    ThresholdMap.from_backlash(B, -5.3, 5.3))
    blob = T.build_table(B, f, -5.0, 5.0, "mm", transition=tr, relax=Relaxation(0.4, 0.3)).blob
    assert T.header(blob).layout_version == 5 and T.CalibTable(blob).cal.relax.kappa_q16 != 0
    sent, q_host = _host_run(blob)
    assert _qemu_flash_and_compensate(blob, sent) == q_host
