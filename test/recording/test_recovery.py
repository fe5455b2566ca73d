"""A recording cut by SIGKILL: the standard MCAP reader fails on it; ``record --recover`` writes
a complete copy that it opens, with every message of the closed chunks."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.exceptions import McapError

from crawler_motion.recording.reader import read_recording
from crawler_motion.recording.recorder import main as record_main

mcap_reader = pytest.importorskip("mcap.reader")

WRITER = """
import sys, time
from crawler_motion.recording.sink import McapSink
sink = McapSink(sys.argv[1], chunk_size=4096)
i = 0
while True:
    text = b"hello %06d" % i
    cdr = b"\\x00\\x01\\x00\\x00" + (len(text) + 1).to_bytes(4, "little") + text + b"\\x00"
    sink.write("/chatter", "std_msgs/msg/String", cdr, time.time_ns())
    i += 1
    if i % 100 == 0:
        print(i, flush=True)
        time.sleep(0.005)
"""


def standard_count(path: Path) -> int:
    with open(path, "rb") as f:
        return sum(1 for _ in mcap_reader.make_reader(f).iter_messages())


def test_a_killed_recording_is_recovered_for_the_standard_reader(tmp_path: Path, capsys) -> None:
    cut = tmp_path / "cut.mcap"
    proc = subprocess.Popen([sys.executable, "-c", WRITER, str(cut)], stdout=subprocess.PIPE,
                            text=True)
    assert proc.stdout is not None
    while int(proc.stdout.readline() or 0) < 3000:  # several chunks and flush periods
        assert proc.poll() is None
    time.sleep(1.2)  # past a flush period
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    with pytest.raises(McapError):  # no footer: the standard reader cannot open it
        standard_count(cut)
    kept = read_recording(cut)
    assert kept.damage is not None and kept.count >= 3000
    assert record_main(["--recover", str(cut)]) == 0
    fixed = tmp_path / "cut.recovered.mcap"
    assert f"recovered {kept.count} messages into {fixed}" in capsys.readouterr().out
    assert standard_count(fixed) == kept.count
    again = read_recording(fixed)
    assert again.damage is None and again.topic("chatter")[-1][1].data == (
        kept.topic("chatter")[-1][1].data)


def test_recover_refuses_what_it_cannot_do(tmp_path: Path, capsys) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all")
    assert record_main(["--recover", str(junk)]) == 1
    assert "no readable message" in capsys.readouterr().err
    assert not (tmp_path / "junk.recovered.mcap").exists()
    assert record_main(["--recover", str(junk), "-o", str(junk)]) == 1
    assert "onto itself" in capsys.readouterr().err
    assert record_main(["--recover", str(tmp_path / "missing.mcap")]) == 1
