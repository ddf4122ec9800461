"""`softcbf simulate --mcap` read back by an independent reader, the `mcap` package:
channels, schemas, message counts, times and values against the run's CSV files, and the
metadata against summary.json. Skipped where `mcap` is not installed (.ci/python installs
it)."""

import csv
import json

import pytest

from conftest import run_cli

reader_module = pytest.importorskip("mcap.reader", reason="the mcap package is not installed")

KINDS = ["joint_states", "commands", "barriers"]


def read_csv(path):
    with open(path, newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    return rows[0], [[float(v) for v in row] for row in rows[1:]]


def columns(header, prefix):
    return [k for k, name in enumerate(header) if name.startswith(prefix)]


def test_simulate_writes_an_mcap_log_of_its_csv(softcbf_bin, tmp_path):
    run_cli(softcbf_bin, "simulate", "--duration", 0.05, "--compare", "--mcap",
            "--out", tmp_path, check=False)
    with open(tmp_path / "run.mcap", "rb") as handle:
        reader = reader_module.make_reader(handle)
        summary = reader.get_summary()
        channels = {c.topic: c for c in summary.channels.values()}
        assert sorted(channels) == sorted(f"/{run}/{kind}" for run in ["filter", "pd"]
                                          for kind in KINDS)
        for channel in channels.values():
            assert channel.message_encoding == "json"
            schema = summary.schemas[channel.schema_id]
            assert schema.encoding == "jsonschema" and json.loads(schema.data)["type"] == "object"
        messages = {}
        for _schema, channel, message in reader.iter_messages():
            messages.setdefault(channel.topic, []).append(message)
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}

    for run, csv_name in [("filter", "trajectory.csv"), ("pd", "trajectory_pd.csv")]:
        header, rows = read_csv(tmp_path / csv_name)
        tau, tau_nom = columns(header, "tau "), columns(header, "tau_nom ")
        n = len(tau)  # t, then q, dq/dt, tau, tau_nom (n each), then the barriers
        q, qd = list(range(1, 1 + n)), list(range(1 + n, 1 + 2 * n))
        b = columns(header, "b ")
        labels = [header[k][2:header[k].rindex(" [")] for k in b]
        units = [header[k][header[k].rindex(" [") + 2:-1] for k in b]
        barriers = channels[f"/{run}/barriers"]
        assert json.loads(barriers.metadata["labels"]) == labels
        assert json.loads(barriers.metadata["units"]) == units
        for kind in KINDS:
            assert summary.statistics.channel_message_counts[channels[f"/{run}/{kind}"].id] \
                == len(rows)
        decoded = {kind: [json.loads(m.data) for m in messages[f"/{run}/{kind}"]]
                   for kind in KINDS}
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

    written = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    assert {k: json.loads(v) for k, v in metadata["settings"].items()} == written["settings"]
    for field in ["rows", "controller", "duration", "min_barrier", "counts"]:
        assert json.loads(metadata["summary"][field]) == written[field]
