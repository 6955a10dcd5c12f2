"""akd-plot: pictures of bags recorded by akd_ros.recorder with the package's own messages."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import pytest
from sensor_msgs.msg import JointState

from akd_ros.cli.plot import io_steps, main, read_run
from akd_ros.msg import CycleSample, DriveFault, DriveIO, LatchEvent
from akd_ros.recorder import Recorder

T0 = 1_700_000_000_000_000_000
RATE_HZ = 1000
PERIOD_NS = 1_000_000_000 // RATE_HZ
FAULT_CYCLE, LATCH_CYCLE, CYCLES = 2500, 1200, 3000


def cycle_sample(i: int) -> CycleSample:
    """A move that stalls: the axis follows its command until 2.3 s, then lags until the fault
    (following error limit) at 2.5 s, after which the power stage is off and the torque 0."""
    msg = CycleSample()
    msg.stamp.sec, msg.stamp.nanosec = divmod(T0 + i * PERIOD_NS, 1_000_000_000)
    msg.cycle = i
    t = i / RATE_HZ
    msg.command = 2.0 * (1 - math.cos(math.pi * min(t, 2.9) / 2.9))
    stall = max(0.0, t - 2.3)
    msg.following_error = 0.002 * math.sin(20 * t) + (0.5 * stall**0.5 if i <= FAULT_CYCLE else 0.0)
    msg.position = msg.command - msg.following_error if i <= FAULT_CYCLE else 2.4
    msg.velocity = 0.0
    msg.torque = (1.5 + 20 * stall if stall else 0.8 * math.sin(2 * t)) if i <= FAULT_CYCLE else 0.0
    msg.position_counts = int(msg.position * 2**20 / (2 * math.pi))
    msg.statusword = 0x0637 if i <= FAULT_CYCLE else 0x0218
    msg.mode_of_operation = 8
    # Jitter of +-20 us, and one late cycle that the histogram must show.
    msg.period_ns = 1_800_000 if i == 2000 else PERIOD_NS + (i * 7919 % 41 - 20) * 1000
    msg.exchange_ns = 80_000
    msg.wkc = 3
    return msg


def drive_io(i: int) -> DriveIO:
    """The axis's I/O at cycle i: input 3 (named part_present) high from 0.5 s to 1.5 s, the positive limit switch
    active from 2.2 s, output 2 (named lamp) on from 1 s; input 1 never high."""
    t = i / RATE_HZ
    msg = DriveIO(joint="axis", cycle=i, digital_inputs_mapped=True, digital_outputs_mapped=True)
    msg.inputs = [False, False, 0.5 <= t < 1.5, False, False, False, False]
    msg.positive_limit = t >= 2.2
    msg.input_names, msg.input_numbers, msg.named_inputs = ["part_present"], [3], [msg.inputs[2]]
    msg.outputs = [False, t >= 1.0]
    msg.output_names, msg.output_numbers, msg.named_outputs = ["lamp"], [2], [msg.outputs[1]]
    msg.hardware_enable = DriveIO.HARDWARE_ENABLE_HIGH
    msg.analog_input = msg.analog_output = 0.0
    return msg


def record(folder: Path, decimation: int = 4, io: bool = False) -> Path:
    """Records the stalled move with a latch capture and the fault (and with `io` the axis's I/O every 100 cycles);
    returns the bag."""
    options = {"cycle_rate_hz": RATE_HZ, "decimation": decimation, "black_box_seconds": 1.0}
    with Recorder(folder, **options) as recorder:
        recorder.add_cycle_topic("/akd_node/cycle", CycleSample)
        recorder.add_topic("/akd_node/latch", LatchEvent)
        recorder.add_topic("/akd_node/fault", DriveFault)
        if io:
            recorder.add_topic("/akd_node/io", DriveIO)
        for i in range(CYCLES):
            time_ns = T0 + i * PERIOD_NS
            sample = cycle_sample(i)
            recorder.cycle_sample(sample, time_ns)
            if io and i % 100 == 0:
                message = drive_io(i)
                message.header.stamp = sample.stamp
                recorder.write("/akd_node/io", message, time_ns)
            if i == LATCH_CYCLE:
                latch = LatchEvent(
                    joint="axis",
                    channel=1,
                    edge=LatchEvent.EDGE_RISING,
                    position=sample.position,
                    position_counts=sample.position_counts,
                )
                latch.header.stamp = sample.stamp
                recorder.write("/akd_node/latch", latch, time_ns)
            if i == FAULT_CYCLE:
                fault = DriveFault(
                    joint="axis",
                    source="drive_fault",
                    code=0x8611,
                    text="F439 following error",
                    ds402_state="fault",
                    al_state="op",
                    al_status_code=0,
                    action="power stage off",
                )
                fault.header.stamp = sample.stamp
                recorder.write("/akd_node/fault", fault, time_ns)
                recorder.fault(time_ns)
    return recorder.bag_path


def png_size(path: Path) -> tuple[int, int]:
    """Width and height from a PNG's IHDR chunk, after checking the signature."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def test_plot_of_a_run_with_a_fault_and_a_latch(tmp_path, capsys):
    bag = record(tmp_path)
    output = tmp_path / "run.png"
    assert main([str(bag), "-o", str(output)]) == 0
    assert capsys.readouterr().out.strip() == str(output)
    width, height = png_size(output)
    assert (width, height) == (1300, 1100)
    # A picture with curves and labels in it, not an empty canvas.
    assert output.stat().st_size > 50_000


def test_plot_from_the_black_box_alone(tmp_path):
    bag = record(tmp_path, decimation=0)
    output = tmp_path / "black_box.svg"
    assert main([str(bag), "-o", str(output)]) == 0
    text = output.read_text()
    assert text.startswith("<?xml") and "F439 following error" in text and "latch 1 rising" in text


def test_missing_bag_is_named(tmp_path, capsys):
    assert main([str(tmp_path / "nothing"), "-o", str(tmp_path / "x.png")]) == 1
    expected = f"akd-plot: error: no bag at {tmp_path / 'nothing'}: expected a rosbag2 directory"
    assert expected in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()


def test_bag_without_cycle_samples_is_named_with_its_topics(tmp_path, capsys):
    with Recorder(tmp_path, cycle_rate_hz=RATE_HZ) as recorder:
        recorder.add_topic("/joint_states", JointState)
        recorder.write("/joint_states", JointState(name=["a"], position=[1.0]), T0)
    assert main([str(recorder.bag_path), "-o", str(tmp_path / "x.png")]) == 1
    assert capsys.readouterr().err.strip() == (
        f"akd-plot: error: bag {recorder.bag_path} has no akd_ros/msg/CycleSample messages "
        "(its topics: /joint_states (sensor_msgs/msg/JointState))"
    )


def test_output_type_is_checked_before_reading(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([str(tmp_path), "-o", str(tmp_path / "x.jpg")])
    assert exit_info.value.code == 2
    assert "must end in one of .png, .svg, .pdf" in capsys.readouterr().err


def test_killed_recording_needs_and_gets_reindex(tmp_path, capsys):
    bag = record(tmp_path)
    # What a SIGKILL leaves: the file cut inside its summary (no footer).
    mcap_file = next(bag.glob("*.mcap"))
    mcap_file.write_bytes(mcap_file.read_bytes()[:-200])
    output = tmp_path / "run.png"
    assert main([str(bag), "-o", str(output)]) == 1
    assert "run akd-plot with --reindex" in capsys.readouterr().err
    assert main([str(bag), "-o", str(output), "--reindex"]) == 0
    assert png_size(output) == (1300, 1100)


def test_the_io_is_drawn_as_steps_by_the_names_the_node_gave(tmp_path):
    bag = record(tmp_path, io=True)
    steps = dict(io_steps(read_run(bag).io))
    # The named ones always, the others once high; input 1 never was.
    assert list(steps) == ["part_present", "positive limit", "lamp"]
    assert steps["part_present"] == [0.5 <= i / 10 < 1.5 for i in range(CYCLES // 100)]
    output = tmp_path / "io.svg"
    assert main([str(bag), "-o", str(output)]) == 0
    text = output.read_text()
    assert "part_present" in text and "positive limit" in text and "lamp" in text and "DI1" not in text
    png = tmp_path / "io.png"
    assert main([str(bag), "-o", str(png)]) == 0
    assert png_size(png) == (1300, 1300)
