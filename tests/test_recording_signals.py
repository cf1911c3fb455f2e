"""SIGTERM during `fly` finalises the recording and the video (as Ctrl-C does); a recording cut
by SIGKILL is repaired as docs/guide.md says."""

import signal
import subprocess
import sys
import time

import imageio.v3 as iio

from tests.test_review import RERUN

# the CLI as installed, with the recorder flushing every 0.5 s so the test need not wait 5 s
_FLY = """
import sys
import cpp_mujoco.review.recording as recording
recording.FLUSH_SECONDS = 0.5
from cpp_mujoco.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


def _verify(path) -> subprocess.CompletedProcess:
    return subprocess.run([RERUN, "rrd", "verify", str(path)], capture_output=True, text=True)


def test_sigterm_finalises_recording_and_video_and_exits_143(tmp_path):
    rrd, video = tmp_path / "m.rrd", tmp_path / "chase.mp4"
    argv = ["fly", "--map", "A", "--agent", "A", "--budget", "60", "--start", "12,2",
            "--rrd", str(rrd), "--video", str(video), "--no-progress"]  # fmt: skip
    proc = subprocess.Popen(
        [sys.executable, "-c", _FLY, *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 120
        while not (
            rrd.exists() and rrd.stat().st_size > 60_000
        ):  # mission data beyond the ~36 kB scene
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no recording data after 120 s"
            time.sleep(0.1)
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 143, err
    assert "Traceback" not in err and "interrupted (SIGTERM)" in err
    partial = tmp_path / "chase.partial.mp4"
    assert str(rrd) in err and str(partial) in err  # the message names what was finalised
    assert _verify(rrd).returncode == 0  # footer written: before, "Missing RRD footer"
    assert not video.exists() and iio.imread(partial).shape[0] > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["chase.partial.mp4", "m.rrd"]

    # SIGKILL leaves no footer; the repair docs/guide.md gives keeps every complete message
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(rrd.read_bytes()[: int(rrd.stat().st_size * 0.7)])
    assert _verify(cut).returncode != 0
    repaired = tmp_path / "repaired.rrd"
    subprocess.run(
        [RERUN, "rrd", "optimize", str(cut), "-o", str(repaired)], capture_output=True, check=True
    )
    assert _verify(repaired).returncode == 0
