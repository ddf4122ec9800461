"""`softcbf simulate --mcap` read back by an independent reader, the `mcap` package:
channels, schemas, message counts, times and values against the run's CSV files (the QP's
status and reason per tick among them), the metadata against summary.json, and the robot
in 3-D (`foxglove.SceneUpdate`, `foxglove.FrameTransform`) against the CSV's barriers.
Skipped where `mcap` is not installed (.ci/python installs it)."""

import csv
import json

import pytest

from conftest import run_cli

reader_module = pytest.importorskip("mcap.reader", reason="the mcap package is not installed")

ROW_KINDS = ["joint_states", "commands", "barriers", "qp", "extra"]
KINDS = ROW_KINDS + ["scene"]

# docs/hardware.md's table of the `status` and `reason` columns.
STATUS_NAMES = {-1: "no-reading", 0: "unfiltered", 1: "filtered", 2: "relaxed",
                3: "qp-failed", 4: "invalid", 5: "uncertified"}
REASON_NAMES = {0: None, 1: "tube", 2: "domain", 3: "start", 4: "bound", 5: "budget",
                6: "non-finite", 7: "size", 8: "mass-matrix", 9: "non-finite-model",
                10: "out-of-domain"}

DURATION = 1.0  # s: PD+ is past a corner's margin from 0.45 s on, the filter nowhere


def read_csv(path):
    with open(path, newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    return rows[0], [[float(v) for v in row] for row in rows[1:]]


def columns(header, prefix):
    return [k for k, name in enumerate(header) if name.startswith(prefix)]


@pytest.fixture(scope="module")
def log(softcbf_bin, tmp_path_factory):
    out = tmp_path_factory.mktemp("mcap")
    run_cli(softcbf_bin, "simulate", "--duration", DURATION, "--compare", "--mcap",
            "--out", out, check=False)
    with open(out / "run.mcap", "rb") as handle:
        reader = reader_module.make_reader(handle)
        summary = reader.get_summary()
        messages = {}
        for _schema, channel, message in reader.iter_messages():
            messages.setdefault(channel.topic, []).append(message)
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    return out, summary, messages, metadata


def test_channels_and_schemas(log):
    _out, summary, _messages, _metadata = log
    channels = {c.topic: c for c in summary.channels.values()}
    assert sorted(channels) == sorted([f"/{run}/{kind}" for run in ["filter", "pd"]
                                       for kind in KINDS] + ["/tf"])
    for channel in channels.values():
        assert channel.message_encoding == "json"
        schema = summary.schemas[channel.schema_id]
        assert schema.encoding == "jsonschema"
        assert json.loads(schema.data)["type"] == "object"
    names = {topic: summary.schemas[c.schema_id].name for topic, c in channels.items()}
    assert names["/filter/scene"] == names["/pd/scene"] == "foxglove.SceneUpdate"
    assert names["/tf"] == "foxglove.FrameTransform"
    assert names["/filter/qp"] == "softcbf.QpStatus"
    scene_schema = json.loads(summary.schemas[channels["/pd/scene"].schema_id].data)
    assert {"deletions", "entities"} <= set(scene_schema["properties"])


def test_rows_are_the_csvs(log):
    out, summary, messages, _metadata = log
    channels = {c.topic: c for c in summary.channels.values()}
    for run, csv_name in [("filter", "trajectory.csv"), ("pd", "trajectory_pd.csv")]:
        header, rows = read_csv(out / csv_name)
        tau, tau_nom = columns(header, "tau "), columns(header, "tau_nom ")
        n = len(tau)  # t, then q, dq/dt, tau, tau_nom (n each), then the barriers
        q, qd = list(range(1, 1 + n)), list(range(1 + n, 1 + 2 * n))
        b = columns(header, "b ")
        extra = list(range(b[-1] + 1, len(header)))
        assert [header[k] for k in extra] == ["status", "reason"]
        labels = [header[k][2:header[k].rindex(" [")] for k in b]
        units = [header[k][header[k].rindex(" [") + 2:-1] for k in b]
        barriers = channels[f"/{run}/barriers"]
        assert json.loads(barriers.metadata["labels"]) == labels
        assert json.loads(barriers.metadata["units"]) == units
        assert json.loads(channels[f"/{run}/extra"].metadata["names"]) == ["status", "reason"]
        for kind in ROW_KINDS:
            assert summary.statistics.channel_message_counts[channels[f"/{run}/{kind}"].id] \
                == len(rows)
        decoded = {kind: [json.loads(m.data) for m in messages[f"/{run}/{kind}"]]
                   for kind in ROW_KINDS}
        statuses = set()
        for k, row in enumerate(rows):
            state = decoded["joint_states"][k]
            assert messages[f"/{run}/joint_states"][k].log_time == round(row[0] * 1e9)
            assert state["t"] == row[0]
            assert state["name"] == [header[j][:header[j].index(" [")] for j in q]
            assert state["position"] == [row[j] for j in q]
            assert state["velocity"] == [row[j] for j in qd]
            assert decoded["commands"][k]["tau"] == [row[j] for j in tau]
            assert decoded["commands"][k]["tau_nom"] == [row[j] for j in tau_nom]
            assert decoded["barriers"][k]["values"] == [row[j] for j in b]
            assert decoded["extra"][k]["values"] == [row[j] for j in extra]
            status, reason = row[extra[0]], row[extra[1]]
            qp = decoded["qp"][k]
            assert messages[f"/{run}/qp"][k].log_time == round(row[0] * 1e9)
            assert qp["t"] == row[0]
            assert (qp["status_code"], qp["reason_code"]) == (status, reason)
            assert qp["status"] == STATUS_NAMES[int(status)]
            assert qp["reason"] == REASON_NAMES[int(reason)]
            statuses.add(qp["status"])
        assert statuses == ({"unfiltered"} if run == "pd" else {"filtered"}), statuses


def test_metadata_is_the_summary(log):
    out, _summary, _messages, metadata = log
    written = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert {k: json.loads(v) for k, v in metadata["settings"].items()} == written["settings"]
    rest = {k: json.loads(v) for k, v in metadata["summary"].items()}
    assert rest == {k: v for k, v in written.items() if k != "settings"}
    assert rest["comparison"]["controller"] == "pd"


def test_the_scene_draws_the_robot_at_thirty_frames_per_second(log):
    out, summary, messages, _metadata = log
    channels = {c.topic: c for c in summary.channels.values()}
    transforms = [json.loads(m.data) for m in messages["/tf"]]
    assert {(t["parent_frame_id"], t["child_frame_id"]) for t in transforms} \
        == {("world", "filter"), ("world", "pd")}
    for run, csv_name in [("filter", "trajectory.csv"), ("pd", "trajectory_pd.csv")]:
        header, rows = read_csv(out / csv_name)
        times = {round(row[0] * 1e9): row for row in rows}
        corners = [k for k in columns(header, "b ") if " corner " in header[k]]
        scene = messages[f"/{run}/scene"]
        # 30 frames per second of robot time, the first and the last row among them.
        assert len(scene) == round(30 * DURATION) + 1
        assert summary.statistics.channel_message_counts[channels[f"/{run}/scene"].id] \
            == len(scene)
        assert scene[0].log_time == 0 and scene[-1].log_time == round(DURATION * 1e9)
        violated_seen = False
        for message in scene:
            assert message.log_time in times, "a frame is stamped with a row's time"
            row = times[message.log_time]
            update = json.loads(message.data)
            entities = {e["id"]: e for e in update["entities"]}
            assert set(entities) == {"robot", "obstacles"}
            robot = entities["robot"]
            assert robot["frame_id"] == run
            stamp = robot["timestamp"]
            assert stamp["sec"] * 10**9 + stamp["nsec"] == message.log_time
            # Two backbones from the base, six tendons, three plate outlines, and the
            # corner gaps; one sphere per corner barrier, coloured by its value.
            assert robot["lines"][0]["points"][0] == {"x": 0.0, "y": 0.0, "z": 0.0}
            spheres = robot["spheres"]
            assert len(spheres) == len(corners)
            colour = [tuple(sorted(s["color"].items())) for s in spheres]
            violated = [row[k] < -1e-6 for k in corners]
            if any(violated) and not all(violated):
                violated_seen = True
                red = {c for c, v in zip(colour, violated) if v}
                others = {c for c, v in zip(colour, violated) if not v}
                assert len(red) == 1 and not red & others, (message.log_time, colour)
        assert violated_seen == (run == "pd"), run
