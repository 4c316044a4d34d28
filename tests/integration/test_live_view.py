"""The live view's JSON on a finished run folder: progress complete, the shares equal to the
run's metrics.json (and to a count of the CSV's outcomes), the map's layer, the HTTP routes."""

from __future__ import annotations

import csv
import json
import threading
import time
import urllib.error
import urllib.request

import pytest

from veriloc_rt.cli import main
from veriloc_rt.config import Config, config_to_dict
from veriloc_rt.detectors.outcomes import OUTCOMES
from veriloc_rt.live.server import TOKEN_HEADER, LiveServer
from veriloc_rt.live.state import RunFolderState

#: a tiny UMa run: two scenarios, no encrypted-PRS pass, DigSig from the HMAC chain's checks
TINY = {"propagation": {"model": "uma"}, "trajectory": {"num_points": 8, "adversary_lag_points": 2},
        "run": {"scenarios": ["none", "fbs"], "evaluate_encrypted": False, "digsig": "shared"}}
#: a child ``veriloc-rt run`` that fails on its input: interpreter start and imports, s
RUN_START_TIMEOUT_S = 60.0
#: shares are ratios of small counts; the JSON round trip keeps floats exact
EXACT = 1e-12


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    d = tmp_path_factory.mktemp("live")
    cfg = d / "c.json"
    cfg.write_text(json.dumps(TINY))
    assert main(["run", str(cfg), "--out", str(d / "r"), "--workers", "1"]) == 0
    return d / "r"


def test_state_of_a_finished_run_equals_its_metrics(finished):
    metrics = json.loads((finished / "metrics.json").read_text())["scenarios"]
    view = RunFolderState(finished)
    st = json.loads(json.dumps(view.state("fbs")))
    assert (st["status"], st["stage"], st["eta_s"]) == ("complete", "done", 0.0)
    assert [s["name"] for s in st["scenarios"]] == ["none", "fbs"]
    for s in st["scenarios"]:
        assert (s["done"], s["total"], s["eta_s"]) == (8, 8, 0.0)
        assert s["metrics"] == metrics[s["name"]]
    # the benign shares counted from the CSV directly
    with open(finished / "none_results.csv", newline="") as fh:
        outcomes = [r["outcome"] for r in csv.DictReader(fh)]
    none = st["scenarios"][0]["metrics"]["outcomes"]
    for k in OUTCOMES:
        assert none[k] == pytest.approx(outcomes.count(k) / len(outcomes), abs=EXACT)   # fraction
    p = st["points"]
    assert p["scenario"] == "fbs" and p["index"] == list(range(8))
    window = [i for i, a in enumerate(p["attack"]) if a]
    # run.attack_points: floor(0.25 * 8) = 2 up to floor(0.75 * 8) = 6
    assert window == [2, 3, 4, 5]
    view.wait_scene(60)
    scene = view.scene()
    summary = json.loads((finished / "propagation_summary.json").read_text())
    assert scene["ready"] and scene["attack"] == [2, 6]
    assert len(scene["bs"]) == summary["num_bs"] and len(scene["ue"]) == 8
    # the run chose among no candidate sites: every BS drawn alike, as the run's maps do
    assert summary["serving_bs"] is None and st["serving"] is None
    assert len(scene["buildings"]) == summary["num_buildings"]
    # the true positions of the map's layer are the run's (same seed, same geometry)
    assert [xy for xy in zip(p["x_true"], p["y_true"])] == [tuple(u) for u in scene["ue"]]


def _get(url: str, token: str | None = None):
    req = urllib.request.Request(url, headers={} if token is None else {TOKEN_HEADER: token})
    with urllib.request.urlopen(req, timeout=30) as r:
        return r.status, r.headers.get("Content-Type"), r.read()


def test_http_routes(finished):
    server = LiveServer(finished, port=0).start()
    try:
        base, token = f"http://127.0.0.1:{server.port}/", server.token
        assert server.url == base + "?token=" + token
        status, ctype, body = _get(base + "api/state?scenario=none&from=6", token)
        st = json.loads(body)
        assert status == 200 and ctype.startswith("application/json")
        assert st["points"]["from"] == 6 and st["points"]["index"] == [6, 7]
        for page, marker in (("", b"decisions"), ("edit", b"Save and run")):
            status, ctype, body = _get(base + page)
            assert ctype.startswith("text/html") and marker in body
        fields = json.loads(_get(base + "api/form", token)[2])["fields"]
        assert any(f["path"] == "trajectory.num_points" for f in fields)
        cfg = json.loads(_get(base + "api/config", token)[2])
        assert cfg["config"]["trajectory"]["num_points"] == 8   # the run's own config
        assert cfg["editable"] is False and cfg["path"] == ""   # a view saves nothing
        with pytest.raises(urllib.error.HTTPError) as e:
            _get(base + "static/../state.py")
        assert e.value.code == 404
        e.value.close()
        # a POST without the page's header is refused (another origin cannot add it)
        req = urllib.request.Request(base + "api/validate", data=b'{"config": {}}',
                                     headers={"Content-Type": "application/json",
                                              TOKEN_HEADER: token})
        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(req, timeout=30)
        assert e.value.code == 403
        e.value.close()
        req.add_header("X-Veriloc", "1")
        with urllib.request.urlopen(req, timeout=30) as r:
            assert json.loads(r.read()) == {"ok": True}
        # a view server saves nothing
        save = urllib.request.Request(base + "api/save", data=b'{"config": {}}',
                                      headers=dict(req.header_items()))
        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(save, timeout=30)
        assert e.value.code == 403 and json.loads(e.value.read())["field"] == "edit"
        e.value.close()
        assert not (finished.parent / f"{finished.name}.json").exists()
    finally:
        server.shutdown()


@pytest.mark.parametrize("args, line", [
    (["run", "--port", "8000"], "error: --port: only with --live"),
    (["run", "--no-browser"], "error: --no-browser: only with --live"),
    (["view", "{tmp}", "--port", "70000"],
     "error: --port: got 70000, expected 0..65535 (0: any free port)"),
    (["view", "{tmp}/f.txt"], "error: {tmp}/f.txt: not a folder (give a run's --out folder)"),
    (["edit", "{tmp}/bad.json"],
     "error: trajectory.num_points: got 1, expected a value >= 2 and <= 10000"),
])
def test_bad_flags_of_the_live_commands_are_one_line(tmp_path, capsys, args, line):
    (tmp_path / "f.txt").write_text("x")
    (tmp_path / "bad.json").write_text(json.dumps({"trajectory": {"num_points": 1}}))
    args = [a.format(tmp=tmp_path) for a in args]
    assert main([*args, "--out", str(tmp_path / "o")] if args[0] == "run" else args) == 2
    assert capsys.readouterr().err.strip() == line.format(tmp=tmp_path)


def test_editor_on_a_new_config_file_starts_from_the_default(tmp_path):
    server = LiveServer(tmp_path / "out", config_path=tmp_path / "new.json", port=0, edit=True)
    st = server.editor_state()
    assert st["path"] == str(tmp_path / "new.json") and st["out"] == str(tmp_path / "out")
    assert st["config"] == config_to_dict(Config()) and st["editable"] is True
    # closing a server that never served returns at once (http.server's shutdown would wait)
    t = threading.Thread(target=server.shutdown)
    t.start()
    t.join(10)
    assert not t.is_alive()


def test_editor_without_a_run_answers_that_there_is_no_run_map(tmp_path):
    """``veriloc-rt edit`` before any run: the map's layer says at once that there is no run
    (the page shows that, instead of "building the map" forever) and builds nothing; the form's
    routes answer."""
    server = LiveServer(tmp_path / "out", config_path=tmp_path / "new.json", port=0,
                        edit=True).start()
    try:
        base, token = f"http://127.0.0.1:{server.port}/", server.token
        layer = json.loads(_get(base + "api/scene", token)[2])
        assert layer["ready"] is False and layer["run"] is False
        assert json.loads(_get(base + "api/state", token)[2])["status"] == "waiting"
        assert any(f["path"] == "trajectory.num_points"
                   for f in json.loads(_get(base + "api/form", token)[2])["fields"])
        assert json.loads(_get(base + "api/config", token)[2])["editable"] is True
    finally:
        server.shutdown()


def test_a_run_the_editor_starts_that_fails_shows_its_error_line(tmp_path, capsys):
    (tmp_path / "taken").write_text("a file, not a folder")
    server = LiveServer(tmp_path / "taken", config_path=tmp_path / "c.json", port=0, edit=True)
    try:
        res = server.start_run(dict(TINY), str(tmp_path / "c.json"), str(tmp_path / "taken"))
        assert res["ok"] and json.loads((tmp_path / "c.json").read_text()) == TINY
        deadline = time.monotonic() + RUN_START_TIMEOUT_S
        while time.monotonic() < deadline:
            proc = server.view.state().get("process")
            if proc and proc["returncode"] is not None:
                break
            time.sleep(0.1)
        assert proc["returncode"] == 2
        # the line the same command prints in this process
        assert main(["run", str(tmp_path / "c.json"), "--out", str(tmp_path / "taken")]) == 2
        assert proc["message"] == capsys.readouterr().err.strip()
    finally:
        server.stop_run()
        server.shutdown()


def test_a_taken_default_port_falls_back_but_a_given_one_is_an_error(tmp_path, monkeypatch):
    import socket

    from veriloc_rt.errors import InputError
    from veriloc_rt.live import server as live_server

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        monkeypatch.setattr(live_server, "DEFAULT_PORT", port)
        s = LiveServer(tmp_path, port=None)     # no --port: the default, else a free one
        try:
            assert s.port not in (port, 0)
        finally:
            s.shutdown()
        with pytest.raises(InputError, match=f"^--port: {port} is in use by another program"):
            LiveServer(tmp_path, port=port)     # --port given: that one or an error
