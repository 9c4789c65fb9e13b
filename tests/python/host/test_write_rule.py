"""One rule for every write (atomic.check_output, atomic_path, check_flash_file,
io.videofile): an output is renamed into place in its folder, never written through a
symbolic link nor over a pipe, a device or a file playscope did not write (by content, not
size); --force replaces only playscope's own files, checked at any depth; a pipe or a device
is refused as an input before anything opens it; a video is whole or absent.

Each case runs the command on the smallest input that shows it (the shared `good` set, or a
3-s simulated session) and checks one stderr line, exit 2, and the SHA-256 of every file
before and after. Commands run in a child process when a hang is possible (a FIFO), under a
timeout, so a hang fails the case instead of the run."""

from __future__ import annotations

import hashlib
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

from playscope.base import atomic
from playscope.base.atomic import FLASH_IMAGE_BYTES
from playscope.cli import main

from .goodfiles import copy_good

PLAYSCOPE = [sys.executable, "-m", "playscope"]


def _state(root) -> dict:
    """path -> SHA-256 of each regular file, or what a link, pipe or device is (never opened)."""
    out = {}
    for dirpath, dirs, names in os.walk(root):
        for n in names + dirs:
            p = os.path.join(dirpath, n)
            st = os.lstat(p)
            if stat.S_ISREG(st.st_mode):
                out[p] = hashlib.sha256(open(p, "rb").read()).hexdigest()
            elif stat.S_ISLNK(st.st_mode):
                out[p] = "link -> " + os.readlink(p)
            else:
                out[p] = stat.S_IFMT(st.st_mode)
    return out


def _one_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("playscope: error: ") and "\n" not in err, err
    return err


def _run(argv, timeout=60, **kw) -> subprocess.CompletedProcess:
    """playscope argv in a child process; a hang fails the test (TimeoutExpired)."""
    return subprocess.run(PLAYSCOPE + [str(a) for a in argv], capture_output=True, text=True, timeout=timeout, **kw)


def _one_line(r: subprocess.CompletedProcess) -> str:
    err = r.stderr.strip()
    assert r.returncode == 2 and err.startswith("playscope: error: ") and "\n" not in err, (r.returncode, err)
    return err


# --------------------------------------------------------------------------- the board's flash file
@pytest.mark.parametrize("force", [[], ["--force"]])
def test_flash_file_of_an_image_size_is_checked_by_content(force, tmp_path, good, capsys):
    """A user's file of exactly an image's size (a raw photo) is not a board image."""
    g = copy_good(good, tmp_path)
    photo = tmp_path / "photo.raw"
    photo.write_bytes(bytes(range(256)) * (FLASH_IMAGE_BYTES // 256))
    before = _state(tmp_path)
    assert main(["flash", str(g["table"]), "--flash-file", str(photo), "--vectors", "5"] + force) == 2
    assert "not a board flash image" in _one_error(capsys)
    assert _state(tmp_path) == before


def test_flash_file_never_through_a_link(tmp_path, good, capsys):
    """A link to a real board image is refused too: the board would write through it."""
    g = copy_good(good, tmp_path)
    img = tmp_path / "board.flash"
    assert main(["flash", str(g["table"]), "--flash-file", str(img), "--vectors", "5"]) == 0
    capsys.readouterr()
    link = tmp_path / "link.flash"
    link.symlink_to(img)
    before = _state(tmp_path)
    assert main(["flash", str(g["table"]), "--flash-file", str(link), "--vectors", "5", "--force"]) == 2
    assert "symbolic link" in _one_error(capsys)
    assert _state(tmp_path) == before
    assert main(["flash", str(g["table"]), "--flash-file", str(img), "--vectors", "5"]) == 0  # the image itself: fine


# --------------------------------------------------------------------------- --force replaces only playscope's
def test_overwrite_keeps_a_users_file_in_a_sub_folder(tmp_path, capsys):
    """simulate S --overwrite: S/session/ holding a user's file is not deleted (only top-level
    names were checked before)."""
    s = tmp_path / "S"
    assert main(["simulate", str(s), "--duration", "3", "--kind", "angle"]) == 0
    (s / "session").mkdir()
    (s / "session" / "notes.txt").write_text("mine\n")
    capsys.readouterr()
    before = _state(tmp_path)
    assert main(["simulate", str(s), "--duration", "3", "--kind", "angle", "--overwrite"]) == 2
    assert "notes.txt" in _one_error(capsys)
    assert _state(tmp_path) == before


def test_overwrite_keeps_a_folder_named_like_a_product(tmp_path, good, capsys):
    """import -o S --overwrite: a folder S/video.avi/ is not a playscope file."""
    g = copy_good(good, tmp_path)
    s = tmp_path / "S"
    assert main(["import", str(g["csv"]), "-o", str(s)]) == 0
    (s / "video.avi").mkdir()
    (s / "video.avi" / "clip.txt").write_text("mine\n")
    capsys.readouterr()
    before = _state(tmp_path)
    assert main(["import", str(g["csv"]), "-o", str(s), "--overwrite"]) == 2
    assert "video.avi" in _one_error(capsys)
    assert _state(tmp_path) == before


def test_overwrite_keeps_a_changed_or_hand_made_session(tmp_path, good, capsys):
    """A session playscope wrote is replaced with --force; one whose file a user edited, or
    one made by hand (no manifest), is not."""
    g = copy_good(good, tmp_path)
    s = tmp_path / "S"
    assert main(["import", str(g["csv"]), "-o", str(s)]) == 0
    assert atomic.folder_not_owned(s) is None
    assert main(["import", str(g["csv"]), "-o", str(s), "--force"]) == 0
    with open(s / "encoder.csv", "a") as fh:
        fh.write("# my note\n")
    capsys.readouterr()
    before = _state(tmp_path)
    assert main(["import", str(g["csv"]), "-o", str(s), "--force"]) == 2
    assert "changed since playscope wrote it" in _one_error(capsys)
    (s / ".playscope").unlink()
    before = _state(tmp_path)
    assert main(["import", str(g["csv"]), "-o", str(s), "--force"]) == 2
    assert "not a file playscope wrote" in _one_error(capsys)
    assert _state(tmp_path) == before


def test_force_replaces_only_files_playscope_wrote(tmp_path, good, capsys):
    """--force over a user's text, or a user's JSON, is refused; over playscope's own JSON
    (--json output) it replaces it."""
    g = copy_good(good, tmp_path)
    mine = tmp_path / "mine.json"
    mine.write_text('{"mine": 1}\n')
    before = _state(tmp_path)
    assert main(["calibrate", str(g["session"]), "-o", str(mine), "--fps", "25", "--force"]) == 2
    assert "did not write" in _one_error(capsys)
    assert _state(tmp_path) == before
    assert atomic.owned_file(g["cal"]) and atomic.owned_file(g["table"]) and not atomic.owned_file(mine)
    out = tmp_path / "t.json"
    assert main(["tables", str(g["cal"]), "-o", str(tmp_path / "t.pstb"), "--json", str(out)]) == 0
    assert atomic.owned_file(out)
    assert main(["tables", str(g["cal"]), "-o", str(tmp_path / "t.pstb"), "--json", str(out), "--force"]) == 0


@pytest.mark.skipif(os.geteuid() != 0, reason="making a device node needs root")
def test_force_never_replaces_a_device_node(tmp_path, good, capsys):
    """tables -o NODE --force, run as root: the node (a copy of /dev/null's) stays a device."""
    g = copy_good(good, tmp_path)
    node = tmp_path / "null"
    os.mknod(node, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    before = _state(tmp_path)
    assert main(["tables", str(g["cal"]), "-o", str(node), "--force"]) == 2
    assert "a device" in _one_error(capsys)
    assert _state(tmp_path) == before and stat.S_ISCHR(os.lstat(node).st_mode)


def test_force_never_writes_through_a_link(tmp_path, good, capsys):
    """-o LINK --force: neither the link nor its target (a playscope table) is replaced."""
    g = copy_good(good, tmp_path)
    link = tmp_path / "link.pstb"
    link.symlink_to(g["table"])
    before = _state(tmp_path)
    assert main(["tables", str(g["cal"]), "-o", str(link), "--force", "--generation", "7"]) == 2
    assert "symbolic link" in _one_error(capsys)
    assert _state(tmp_path) == before


# --------------------------------------------------------------------------- pipes: refused, never opened
@pytest.mark.parametrize("case", ["track-video", "track-session-json", "tables-out", "tables-out-force", "insitu-json", "cal-input"])
def test_a_fifo_is_refused_not_opened(case, tmp_path, good):
    g = copy_good(good, tmp_path)
    fifo = tmp_path / "pipe"
    if case.startswith("track"):
        s = tmp_path / "S"
        assert _run(["simulate", s, "--duration", "3", "--video", "-q"]).returncode == 0
        name = "video.avi" if case == "track-video" else "session.json"
        (s / name).unlink()
        os.mkfifo(s / name)
        argv = ["track", s, "--force"]
    else:
        os.mkfifo(fifo)
        argv = {"tables-out": ["tables", g["cal"], "-o", fifo],
                "tables-out-force": ["tables", g["cal"], "-o", fifo, "--force"],
                "insitu-json": ["evaluate-insitu", g["session"], "--json", fifo, "--force"],
                "cal-input": ["tables", fifo, "-o", tmp_path / "t2.pstb"]}[case]
    before = _state(tmp_path)
    err = _one_line(_run(argv, timeout=60))
    assert "named pipe" in err, err
    assert _state(tmp_path) == before


# --------------------------------------------------------------------------- videos: whole or absent
def test_video_under_a_file_size_limit_is_not_reported_written(tmp_path):
    """simulate --video under ulimit -f: the session files fit, the video does not; nothing is
    left under S (before: "wrote video.avi" with a fraction of the frames decodable)."""
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (300_000, 300_000))

    r = _run(["simulate", tmp_path / "S", "--duration", "3", "--video"], preexec_fn=limit)
    err = _one_line(r)
    assert "frames could be written" in err or "File too large" in err, err
    assert sorted(os.listdir(tmp_path)) == []


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_video_interrupted_leaves_nothing(sig, tmp_path):
    """SIGINT / SIGTERM while the video is written: neither a partial video nor a session
    without frames.csv is left (the temporary folder is removed)."""
    # SIGINT as a shell's foreground job has it: a test runner's worker may ignore SIGINT, and a
    # child inherits that (Python then installs no KeyboardInterrupt handler, as for a background job)
    p = subprocess.Popen(PLAYSCOPE + ["simulate", str(tmp_path / "S"), "--duration", "60", "--video"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    t0 = time.monotonic()
    while time.monotonic() - t0 < 60:  # the video's temporary name appears inside the temporary folder
        tmp = [os.path.join(d, n) for d, _, ns in os.walk(tmp_path) for n in ns if n.endswith(".tmp.avi")]
        try:
            if tmp and os.path.getsize(tmp[0]) > 0:  # frames are being written (not yet counted or renamed)
                break
        except OSError:  # renamed between the walk and the look
            pass
        time.sleep(0.02)
    else:
        p.kill()
        pytest.fail("the video was never started")
    p.send_signal(sig)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 130, (p.returncode, err)
    assert "interrupted" in err and "Traceback" not in err
    assert os.listdir(tmp_path) == []


def test_video_written_whole(tmp_path):
    """The normal case: the video holds every frame frames.csv lists, no temporary is left."""
    from playscope.io.videofile import count_frames

    s = tmp_path / "S"
    assert _run(["simulate", s, "--duration", "3", "--video", "-q"]).returncode == 0
    rows = (s / "frames.csv").read_text().strip().splitlines()[1:]
    assert count_frames(s / "video.avi") == len(rows) > 0
    assert not [n for n in os.listdir(s) if n.startswith(".") and n != ".playscope"]
    assert atomic.folder_not_owned(s) is None
    assert atomic.owned_file(Path(s) / "marker.csv")


def test_main_job_keeps_its_session_folder_its_own(tmp_path):
    """The main job rewrites its excitation session's hand-eye after writing it; the folder's
    manifest follows, so the job's next run may replace the folder (--force semantics)."""
    from playscope.mainjob import declare_registration_error
    from playscope.sim.record import sim_config, write_simulated

    s = tmp_path / "S"
    write_simulated(sim_config("stras", trajectory="excitation", duration_s=2.0, seed=1), s)
    declare_registration_error(s, 2.0)
    assert atomic.folder_not_owned(s) is None


def test_a_session_track_rewrote_is_still_playscopes(tmp_path, capsys):
    """simulate S --video, track S --force (marker.csv rewritten: its hash no longer the
    manifest's), then simulate S --overwrite: replaced, marker.csv being playscope's by its
    header (the main job's second run failed on this)."""
    s = tmp_path / "S"
    assert main(["simulate", str(s), "--duration", "3", "--video", "-q"]) == 0
    assert main(["track", str(s), "--force", "-q"]) == 0
    assert main(["simulate", str(s), "--duration", "3", "--video", "--overwrite", "-q"]) == 0


def test_the_board_itself_never_opens_its_flash_file_through_a_link(tmp_path, good):
    """The host refuses a link as --flash-file; the board does too on its own (O_NOFOLLOW), so a
    link swapped in after the host's check is not written through: the target is unchanged."""
    from playscope.base.native import executable

    target = tmp_path / "target.flash"
    target.write_bytes(b"\xff" * FLASH_IMAGE_BYTES)  # an erased image: the board would take it
    link = tmp_path / "link.flash"
    link.symlink_to(target)
    before = _state(tmp_path)
    r = subprocess.run([str(executable("ps_vboard")), "--stdio", "--flash", str(link)], input=b"",
                       capture_output=True, timeout=30)
    assert r.returncode != 0 and b"link" in r.stderr.lower(), r.stderr
    assert _state(tmp_path) == before
