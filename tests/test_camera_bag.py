"""A camera log as rosbag2 records it — a bag folder written by an independent writer (rosbags,
MCAP storage) — calibrated by ``dhlog process`` end to end (issue 32: "from MCAP and rosbag2
bags")."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from typer.testing import CliRunner

from dhlog.cli.app import app

runner = CliRunner()


def test_a_rosbag2_camera_bag_is_calibrated(tmp_path: Path) -> None:
    """The simulator's small-camera log (16 poses, PNG) copied message by message into a
    rosbag2 bag folder by rosbags' writer: dhlog process takes the folder, finds the camera
    pipeline from its topics and gives the same calibration as from the MCAP file (the camera's
    position equal to 1 µm: the same messages)."""
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as BagWriter
    from rosbags.typesys import Stores, get_typestore

    log = tmp_path / "cam.mcap"
    made = runner.invoke(
        app,
        [
            *("simulate", "kr5", "-o", str(log), "--instrument", "camera"),
            *("--protocol", "random-poses", "--poses", "16", "--camera", "small"),
            *("--image-format", "png", "--seed", "3"),
        ],
    )
    assert made.exit_code == 0, made.output
    store = get_typestore(Stores.ROS2_HUMBLE)
    bag = tmp_path / "bag"
    with log.open("rb") as f, BagWriter(bag, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        connections = {
            cid: w.add_connection(
                channel.topic, summary.schemas[channel.schema_id].name, typestore=store
            )
            for cid, channel in summary.channels.items()
        }
        for _, channel, message in reader.iter_messages():
            w.write(connections[channel.id], message.log_time, message.data)
    shipped = Path(__file__).parents[1] / "pipelines" / "ros2_camera.toml"
    pipeline = tmp_path / "small_board.toml"
    pipeline.write_text(
        shipped.read_text()
        .replace("square_m = 0.04", "square_m = 0.06")
        .replace("marker_m = 0.03", "marker_m = 0.045")
    )
    poses = []
    for source, out in ((log, tmp_path / "from_mcap"), (bag, tmp_path / "from_bag")):
        result = runner.invoke(
            app,
            [
                *("process", str(source), "--nominal", "kr5", "--no-rrd"),
                *("--pipeline", str(pipeline), "--out", str(out)),
            ],
        )
        assert result.exit_code == 0, result.output
        assert "Traceback" not in result.output
        (written,) = out.glob("*.dh.json")
        doc = json.loads(written.read_text())
        assert doc["camera"]["frames"] == 16
        poses.append(np.array(doc["camera"]["T_base_camera"]))
    assert np.allclose(poses[0], poses[1], atol=1e-6)
