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
    """The simulator's small-camera log (16 poses, PNG) copied message by message into rosbag2
    bags by rosbags' writer — MCAP storage, and sqlite3 storage as ROS 2 Humble records by
    default (the folder, and its ``.db3`` file alone): dhlog process takes each, finds the
    camera pipeline from its topics and gives the same calibration as from the MCAP file (the
    camera's position equal to 1 µm: the same messages), naming the bag as its source."""
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
    bags = {"mcap": tmp_path / "bag", "sqlite3": tmp_path / "humble"}
    for (kind, bag), plugin in zip(
        bags.items(), (StoragePlugin.MCAP, StoragePlugin.SQLITE3), strict=True
    ):
        version = 9 if kind == "mcap" else 8
        with log.open("rb") as f, BagWriter(bag, version=version, storage_plugin=plugin) as w:
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
    (db3,) = bags["sqlite3"].glob("*.db3")
    shipped = Path(__file__).parents[1] / "pipelines" / "ros2_camera.toml"
    pipeline = tmp_path / "small_board.toml"
    pipeline.write_text(
        shipped.read_text()
        .replace("square_m = 0.04", "square_m = 0.06")
        .replace("marker_m = 0.03", "marker_m = 0.045")
    )
    poses = []
    for source in (log, bags["mcap"], bags["sqlite3"], db3):
        out = tmp_path / f"from_{source.name}"
        result = runner.invoke(
            app,
            [
                *("process", str(source), "--nominal", "kr5", "--no-rrd"),
                *("--pipeline", str(pipeline), "--out", str(out)),
            ],
        )
        assert result.exit_code == 0, result.output
        assert "Traceback" not in result.output and "dhlog-db3" not in result.output
        (written,) = out.glob("*.dh.json")
        doc = json.loads(written.read_text())
        assert doc["camera"]["frames"] == 16
        assert doc["source"]["path"] == source.name and "dhlog-db3" not in written.read_text()
        poses.append(np.array(doc["camera"]["T_base_camera"]))
    for pose in poses[1:]:
        assert np.allclose(poses[0], pose, atol=1e-6)
    # without a pipeline the sqlite3 bag is still a camera log (the shipped camera pipeline:
    # its 40 mm board is not this log's 60 mm one, which the plausibility check names)
    result = runner.invoke(
        app, ["process", str(db3), "--nominal", "kr5", "--no-rrd", "--out", str(tmp_path / "x")]
    )
    assert result.exit_code == 4, result.output
    assert "about 60.0 mm" in " ".join(result.output.split())
