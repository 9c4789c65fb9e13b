"""Writing a video so it is whole or absent: frames go to a temporary name beside the target,
and the file is renamed onto it only once the writer is released and a re-read counts every
frame written (OpenCV's VideoWriter drops frames without a word when the disk is full or a
file-size limit is hit)."""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path
from typing import Iterator

from ..base.errors import InputError


class CountingWriter:
    """cv2.VideoWriter (MJPG) that counts the frames handed to it."""

    def __init__(self, path: Path, fps: float, size: tuple[int, int]):
        import cv2

        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)  # a failed write is our one error line
        self.path, self.written = path, 0
        self.vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), float(fps), tuple(int(x) for x in size))
        if not self.vw.isOpened():
            raise OSError(f"{path}: OpenCV cannot write an MJPG video here")

    def write(self, img) -> None:
        """Append one frame img (H, W, 3) uint8 BGR at the writer's size; counted in `written`."""
        self.vw.write(img)
        self.written += 1


def count_frames(path: str | os.PathLike) -> int:
    """The number of frames OpenCV decodes from path (grabbed one by one, not the header's count)."""
    import cv2

    # A damaged tail is what is counted here, not an error to print: FFmpeg's decoder writes to
    # file descriptor 2 itself, so it is pointed at /dev/null while counting.
    sys.stderr.flush()
    saved, null = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 2)
    cap = cv2.VideoCapture(str(path))
    n = 0
    try:
        while cap.isOpened() and cap.grab():
            n += 1
    finally:
        cap.release()
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)
    return n


@contextlib.contextmanager
def video_writer(path: str | os.PathLike, fps: float, size: tuple[int, int]) -> Iterator[CountingWriter]:
    """Yield a CountingWriter on a temporary name beside path; on normal exit release it, count
    the frames it holds and rename it onto path only when all are there. Errors: InputError
    naming path (not the temporary) when frames are missing; the temporary is removed on any
    error or interruption."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix or '.avi'}")
    w = None
    try:
        w = CountingWriter(tmp, fps, size)
        yield w
        w.vw.release()
        got = count_frames(tmp)
        if got != w.written:
            raise InputError(path, f"only {got} of {w.written} frames could be written (disk full, or a file-size "
                             "limit such as ulimit -f?); no video written")
        os.replace(tmp, path)
    finally:
        if w is not None:
            w.vw.release()
        if os.path.lexists(tmp):
            tmp.unlink()
