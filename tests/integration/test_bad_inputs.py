"""Every bad input of issue #19 is exit 2 with one line ``error: <field or file>: <problem>``.

Each test is named after the case it reproduces. The CLI runs in this process (``main(argv)``)
except where the case is a hang: those run in a subprocess with a time limit, so that a
regression fails the test instead of hanging the suite. ``config check`` runs every check of a
run's inputs without tracing, so these tests never trace.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import os
import shutil
import socket
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from veriloc_rt.cli import main
from veriloc_rt.errors import InputError
from veriloc_rt.phy.security.keys import generate_keys, key_paths, load_keys
from veriloc_rt.world.scene.export import write_ply

ROOT = Path(__file__).resolve().parents[2]
MINI = ROOT / "scenes" / "mini_canyon"
#: a small canyon config: `config check` builds its geometry in well under a second
TINY = {"seed": 3, "scene": {"extent_m": 140.0, "margin_m": 30.0},
        "trajectory": {"num_points": 12, "region_m": 70.0}}
#: seconds a subprocess may take for a case that used to hang (start-up ~1 s)
HANG_LIMIT_S = 30.0


def run_cli(*args) -> tuple[int, str, str]:
    """``veriloc-rt ARGS`` in this process -> (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in args])
        except SystemExit as exc:  # argparse
            code = exc.code
    return code, out.getvalue(), err.getvalue()


def assert_one_line(code: int, err: str, field: str) -> str:
    """The contract: exit 2, one stderr line ``error: <field>: ...``, no traceback."""
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    field = InputError(field, "").field  # as the message escapes it
    assert lines[0].startswith(f"error: {field}: "), lines[0][:300]
    assert "Traceback" not in err
    return lines[0]


def config_file(tmp_path: Path, data, name: str = "c.json") -> Path:
    f = tmp_path / name
    f.write_text(data if isinstance(data, str) else json.dumps(data))
    return f


def check(tmp_path: Path, data) -> tuple[int, str, str]:
    return run_cli("config", "check", config_file(tmp_path, data))


def external_scene(tmp_path: Path) -> Path:
    """A copy of the shipped mini canyon (scene + trajectory) to damage; returns its folder."""
    dst = tmp_path / "mini"
    shutil.copytree(MINI, dst)
    return dst


def external_config(tmp_path: Path, scene: Path, **extra) -> dict:
    return {"seed": 7, "scene": {"source": str(scene / "scene.xml")},
            "trajectory": {"source": str(scene / "trajectory.csv")}, **extra}


def csv_config(tmp_path: Path, text: str | bytes, **trajectory) -> dict:
    p = tmp_path / "t.csv"
    p.write_bytes(text if isinstance(text, bytes) else text.encode())
    return dict(TINY, trajectory={"source": str(p), **trajectory})


STREET_CSV = "t,x,y\n0,0,0\n1,0,5\n2,0,10\n3,0,15\n4,0,20\n5,0,25\n"


# --- exit 1 where the input is at fault --------------------------------------------------------

def test_config_with_non_utf8_bytes(tmp_path):
    f = tmp_path / "c.json"
    f.write_bytes(b'{"seed": "\xff\xfe"}')
    line = assert_one_line(*run_cli("config", "show", f)[::2], str(f))
    assert "not UTF-8" in line


def test_csv_with_non_utf8_bytes(tmp_path):
    code, _, err = check(tmp_path, csv_config(tmp_path, b"t,x,y\n0,0,0\n1,0,\xff5\n"))
    assert "not UTF-8" in assert_one_line(code, err, "trajectory.source")


def test_json_nested_100000_deep(tmp_path):
    f = config_file(tmp_path, "[" * 100_000 + "]" * 100_000)
    assert "nested" in assert_one_line(*run_cli("config", "show", f)[::2], str(f))


def test_json_integer_of_4301_digits(tmp_path):
    f = config_file(tmp_path, '{"seed": 1' + "0" * 4300 + "}")
    assert_one_line(*run_cli("config", "show", f)[::2], str(f))


@pytest.mark.parametrize("literal", ["1" + "0" * 400, "1" + "0" * 400 + ".5"])
def test_float_field_of_401_digits(tmp_path, literal):
    f = config_file(tmp_path, '{"scene": {"street_width_m": ' + literal + "}}")
    line = assert_one_line(*run_cli("config", "show", f)[::2], "scene.street_width_m")
    assert "finite" in line and len(line) < 300


def test_nul_byte_in_a_path(tmp_path):
    code, _, err = check(tmp_path, dict(TINY, trajectory={"source": "a\u0000b.csv"}))
    assert "NUL" in assert_one_line(code, err, "trajectory.source")
    assert "NUL" in assert_one_line(*run_cli("config", "show", "a\x00b.json")[::2], "a\x00b.json")
    assert_one_line(*run_cli("scene", "--out", "o\x00ut")[::2], "--out")


def test_path_of_5000_characters(tmp_path):
    long = "x" * 5000
    assert "5000 characters" in assert_one_line(*run_cli("config", "show", long)[::2], long)
    code, _, err = check(tmp_path, dict(TINY, trajectory={"source": long + ".csv"}))
    assert_one_line(code, err, "trajectory.source")
    assert_one_line(*run_cli("keys", "--num-bs", 1, "--out", tmp_path / long)[::2], "--out")


def test_ue_array_of_one_element(tmp_path):
    code, _, err = check(tmp_path, dict(TINY, propagation={"ue_array": {"num_elements": 1}}))
    assert_one_line(code, err, "propagation.ue_array.num_elements")


@pytest.mark.parametrize("offsets", [[0, 1, 2, 3], [0, 1, 2, 3, 4]])
def test_more_comb_offsets_than_trps(tmp_path, offsets):
    # fewer offsets than topology.num_trps are completed (tests/unit/config/test_trps_config.py)
    data = dict(TINY, nr={"comb_offsets": offsets, "prs_ids": list(range(len(offsets)))},
                security={"encrypted": [False] * len(offsets)})
    assert "at most 3 offsets" in assert_one_line(*check(tmp_path, data)[::2], "nr.comb_offsets")


def test_tag_slots_empty(tmp_path):
    code, _, err = check(tmp_path, dict(TINY, receiver={"tag_slots": []}))
    assert_one_line(code, err, "receiver.tag_slots")


def test_tag_slots_beyond_slots_per_frame(tmp_path):
    data = dict(TINY, receiver={"tag_slots": [0, 7]}, nr={"slots_per_frame": 5})
    assert "nr.slots_per_frame" in assert_one_line(*check(tmp_path, data)[::2],
                                                   "receiver.tag_slots[1]")


def test_aoa_num_sources_above_the_subarray(tmp_path):
    data = dict(TINY, receiver={"aoa_num_sources": 2},
                propagation={"ue_array": {"num_elements": 3}})
    assert_one_line(*check(tmp_path, data)[::2], "receiver.aoa_num_sources")


def test_stationary_trajectory(tmp_path):
    code, _, err = check(tmp_path, csv_config(tmp_path, "t,x,y\n0,0,0\n1,0,0\n2,0,0\n"))
    assert "never moves" in assert_one_line(code, err, str(tmp_path / "t.csv"))


def test_csv_field_over_128_kb(tmp_path):
    text = "t,x,y\n0,0,0\n1,0," + "5" * 140_000 + "\n"
    code, _, err = check(tmp_path, csv_config(tmp_path, text))
    assert_one_line(code, err, str(tmp_path / "t.csv"))


def _box_ply(path: Path, vertices=None, faces=None) -> None:
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float) if vertices is None else vertices
    f = np.array([[0, 1, 2], [0, 1, 3]]) if faces is None else faces
    write_ply(path, v, f)


#: an ASCII PLY of the box's four vertices and two faces (header: 4 + 2 elements)
ASCII_HEADER = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
                "end_header\n")
ASCII_VERTICES = ["0 0 0", "1 0 0", "0 1 0", "0 0 1"]
ASCII_FACES = ["3 0 1 2", "3 0 1 3"]


@pytest.mark.parametrize("case", ["empty", "garbage", "face_index_out_of_range", "zero_faces",
                                  "ascii_cut_short", "ascii_vertex_row_missing"])
def test_damaged_ply(tmp_path, case):
    scene = external_scene(tmp_path)
    ply = scene / "meshes" / "buildings.ply"
    if case == "empty":
        ply.write_bytes(b"")
    elif case == "garbage":
        ply.write_bytes(os.urandom(2000))
    elif case == "face_index_out_of_range":
        _box_ply(ply, faces=np.array([[0, 1, 2], [0, 1, 99]]))
    elif case == "zero_faces":
        _box_ply(ply, faces=np.zeros((0, 3), int))
    elif case == "ascii_cut_short":       # trimesh alone reads the one face left
        ply.write_text(ASCII_HEADER + "\n".join(ASCII_VERTICES + ASCII_FACES[:1]) + "\n")
    else:                                 # trimesh alone reads the first face row as a vertex
        ply.write_text(ASCII_HEADER + "\n".join(ASCII_VERTICES[:3] + ASCII_FACES) + "\n")
    code, _, err = check(tmp_path, external_config(tmp_path, scene))
    line = assert_one_line(code, err, str(ply))
    if case.startswith("ascii"):
        assert line.endswith(f"{4 + 2 - 1} data rows, but the PLY header declares {4 + 2} "
                             "elements (vertices and faces)")



def check_edited_scene_xml(tmp_path, old: str, new: str) -> str:
    """`config check` on the external test scene with ``old`` replaced by ``new`` in its XML;
    the one error line (about ``scene.source``)."""
    scene = external_scene(tmp_path)
    xml = scene / "scene.xml"
    xml.write_text(xml.read_text().replace(old, new))
    code, _, err = check(tmp_path, external_config(tmp_path, scene))
    return assert_one_line(code, err, "scene.source")


def test_unknown_material(tmp_path):
    line = check_edited_scene_xml(tmp_path, 'value="concrete"', 'value="unobtainium"')
    assert "unknown ITU material" in line


def test_canyon_material_undefined_at_the_carrier(tmp_path):
    data = dict(TINY, scene=dict(TINY["scene"], building_material="floorboard"))
    assert "GHz" in assert_one_line(*check(tmp_path, data)[::2], "scene.building_material")


def test_pkcs8_key_of_an_unknown_type(tmp_path):
    generate_keys(tmp_path / "k", [0])
    pem = key_paths(tmp_path / "k", 0)["sign"]
    import base64

    body = base64.b64decode("".join(pem.read_text().splitlines()[1:-1]))
    # the Ed25519 OID 1.3.101.112 (06 03 2b 65 70) turned into the unassigned 1.3.101.127
    body = body.replace(bytes.fromhex("06032b6570"), bytes.fromhex("06032b657f"))
    pem.write_text("-----BEGIN PRIVATE KEY-----\n" + base64.b64encode(body).decode()
                   + "\n-----END PRIVATE KEY-----\n")
    with pytest.raises(InputError) as exc:
        load_keys(tmp_path / "k", [0])
    assert exc.value.field == str(pem)


def test_keys_out_on_an_existing_file(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    line = assert_one_line(*run_cli("keys", "--num-bs", 1, "--out", f)[::2], "--out")
    assert "not a folder" in line


def test_out_on_a_file(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    assert_one_line(*run_cli("scene", "--out", f)[::2], "--out")
    assert_one_line(*run_cli("scene", "--out", f / "below")[::2], "--out")


def test_out_in_proc():
    assert_one_line(*run_cli("scene", "--out", "/proc/veriloc-out")[::2], "--out")


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into a read-only folder")
def test_out_in_a_read_only_folder(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        assert_one_line(*run_cli("scene", "--out", ro / "out")[::2], "--out")
    finally:
        ro.chmod(0o755)


class _Server:
    """A TCP server on localhost that answers each connection with ``reply`` (None: silence)."""

    def __init__(self, reply: bytes | None):
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.reply, self.conns = reply, []
        self.address = "tcp://127.0.0.1:%d" % self.sock.getsockname()[1]
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.conns.append(conn)
            if self.reply is not None:
                conn.sendall(self.reply)

    def close(self):
        for c in self.conns:
            c.close()
        self.sock.close()


def test_scheduler_that_is_not_dask():
    from veriloc_rt.sim.executors import connect

    server = _Server(b"SSH-2.0-OpenSSH_9.6\r\n")
    try:
        with pytest.raises(InputError) as exc:
            connect(server.address, timeout_s=2.0)
        assert exc.value.field == "--scheduler" and "not a Dask scheduler" in exc.value.problem
    finally:
        server.close()


# --- hangs -------------------------------------------------------------------------------------

def _cli_subprocess(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "veriloc_rt.cli", *map(str, args)],
                          capture_output=True, text=True, cwd=ROOT, timeout=HANG_LIMIT_S)


def test_config_path_is_a_fifo(tmp_path):
    fifo = tmp_path / "c.json"
    os.mkfifo(fifo)
    r = _cli_subprocess("config", "show", fifo)
    assert "not a regular file" in assert_one_line(r.returncode, r.stderr, str(fifo))


def test_key_file_is_a_fifo(tmp_path):
    keys = tmp_path / "keys"
    generate_keys(keys, range(8))
    aes = key_paths(keys, 0)["aes"]
    aes.unlink()
    os.mkfifo(aes)
    f = config_file(tmp_path, dict(TINY, security={"keys_dir": str(keys)}))
    r = _cli_subprocess("config", "check", f)
    assert_one_line(r.returncode, r.stderr, str(aes))


def test_scheduler_that_answers_nothing():
    # an HTTP server waits for a request: Dask's client waited for the handshake forever
    from veriloc_rt.sim.executors import connect

    server = _Server(None)
    try:
        with pytest.raises(InputError) as exc:
            connect(server.address, timeout_s=1.0)
        assert exc.value.field == "--scheduler" and "no Dask handshake" in exc.value.problem
    finally:
        server.close()


# --- accepted but wrong ------------------------------------------------------------------------

def test_duplicate_json_keys(tmp_path):
    f = config_file(tmp_path, '{"seed": -1, "seed": 4}')
    assert "duplicate key 'seed'" in assert_one_line(*run_cli("config", "show", f)[::2], str(f))


def test_attack_window_empty_at_the_runs_length(tmp_path):
    data = dict(TINY, run={"attack_start_fraction": 0.5, "attack_end_fraction": 0.55},
                trajectory=dict(TINY["trajectory"], num_points=4))
    assert "empty" in assert_one_line(*check(tmp_path, data)[::2], "run.attack_end_fraction")
    # the same window holds point 10 of 20 (floor(0.5 x 20) = 10, floor(0.55 x 20) = 11), but
    # --points 4 empties it
    data["trajectory"]["num_points"] = 20
    f = config_file(tmp_path, data)
    assert run_cli("config", "show", f)[0] == 0
    assert_one_line(*run_cli("config", "check", f, "--points", 4)[::2], "run.attack_end_fraction")


def test_attack_window_empty_at_the_csv_length(tmp_path):
    data = csv_config(tmp_path, "t,x,y\n0,0,0\n1,0,5\n2,0,10\n3,0,15\n")
    data["run"] = {"attack_start_fraction": 0.5, "attack_end_fraction": 0.55}
    line = assert_one_line(*check(tmp_path, data)[::2], "run.attack_end_fraction")
    assert "rows of" in line


def test_adversary_lag_beyond_the_trajectory_warns(tmp_path, caplog):
    data = dict(TINY, trajectory=dict(TINY["trajectory"], adversary_lag_points=100_000))
    with caplog.at_level(logging.WARNING):
        code, _, err = check(tmp_path, data)
    assert code == 0, err
    assert any("trajectory.adversary_lag_points" in r.getMessage() for r in caplog.records)


# STREET_CSV: 6 points 1 s and 5 m apart (s = 0, 5, ..., 25 m); the attack window of 6 points
# (0.25 .. 0.75) is points floor(1.5) = 1 up to floor(4.5) = 4: points 1, 2, 3


def _adversary_warnings(tmp_path, caplog, **trajectory) -> list[str]:
    data = csv_config(tmp_path, STREET_CSV, **trajectory)
    with caplog.at_level(logging.WARNING):
        code, _, err = check(tmp_path, data)
    assert code == 0, err
    return [r.getMessage() for r in caplog.records
            if r.getMessage().startswith("trajectory.adversary_lag_points")]


def test_adversary_behind_the_start_in_the_attack_window_warns(tmp_path, caplog):
    # lag 2: points 0, 1 wait behind the start; point 2 is at s = min(s[0], s[2] - 5) = 0, on
    # the path; of the window's points 1, 2, 3 only point 1 is off the path
    (msg,) = _adversary_warnings(tmp_path, caplog, adversary_lag_points=2)
    assert "off the UE's path, at 1 of the 3 attack-window points (it joins the path at point 2)" \
        in msg


def test_adversary_without_lag_coincides_and_warns(tmp_path, caplog):
    # lag 0: s_adv = s - 5 m, exactly the minimum separation behind the UE at every point
    (msg,) = _adversary_warnings(tmp_path, caplog, adversary_lag_points=0)
    assert "rides 5 m behind the UE at each of its 3 points" in msg


def test_adversary_lagging_as_meant_does_not_warn(tmp_path, caplog):
    # lag 1 = 5 m behind, the minimum separation exactly, reached by the lag: not glued
    assert _adversary_warnings(tmp_path, caplog, adversary_lag_points=1) == []
    # the same lag with a 6 m minimum: s_adv(1) = min(0, 5 - 6) = -1 m, off the path at point 1
    (msg,) = _adversary_warnings(tmp_path, caplog, adversary_lag_points=1,
                                 adversary_min_separation_m=6.0)
    assert "at 1 of the 3 attack-window points (it joins the path at point 2)" in msg


def test_adversary_warning_is_one_cli_line(tmp_path):
    f = config_file(tmp_path, csv_config(tmp_path, STREET_CSV, adversary_lag_points=0))
    r = _cli_subprocess("config", "check", f)
    assert r.returncode == 0, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        "WARNING veriloc_rt.sim.checks: trajectory.adversary_lag_points: 0 "), r.stderr
    assert "Traceback" not in r.stderr and r.stdout.startswith("ok: 6 points")


def test_region_larger_than_the_scene(tmp_path):
    data = dict(TINY, trajectory=dict(TINY["trajectory"], region_m=500.0))
    assert "scene.extent_m" in assert_one_line(*check(tmp_path, data)[::2], "trajectory.region_m")


def test_seed_beyond_the_schema():
    assert_one_line(*run_cli("config", "check", "--seed", 2**70)[::2], "--seed")
    assert_one_line(*run_cli("config", "check", "--seed", -1)[::2], "--seed")


def test_points_beyond_the_schema():
    assert_one_line(*run_cli("config", "check", "--points", 10**12)[::2], "--points")
    assert_one_line(*run_cli("bench", "--points", 1, "--out", "x")[::2], "--points")


@pytest.mark.parametrize("command", ["run", "compare", "validate", "bench", "findings"])
def test_huge_points_refused_before_any_work(tmp_path, command):
    # 10**7 points was accepted by a run that then generated the drive for minutes; the maximum
    # (MAX_POINTS) is checked before anything is built, written or traced
    from veriloc_rt.config.world import MAX_POINTS

    out = tmp_path / "out"
    for points in (10**7, MAX_POINTS + 1):
        line = assert_one_line(*run_cli(command, "--points", points, "--out", out)[::2],
                               "--points")
        assert f"<= {MAX_POINTS}" in line
    assert not out.exists()   # refused before the output folder was even created


def test_generated_drive_longer_than_the_generator_takes(tmp_path):
    from veriloc_rt.config.world import MAX_DRIVE_M

    # (num_points - 1) x dt_s x max_speed_mps: 9999 x 3.7 s x 13.9 m/s = 514.2 km > 500 km
    data = {"trajectory": {"num_points": 10_000, "dt_s": 3.7, "max_speed_mps": 13.9}}
    assert 9999 * 3.7 * 13.9 > MAX_DRIVE_M
    line = assert_one_line(*run_cli("config", "show", config_file(tmp_path, data))[::2],
                           "trajectory.num_points")
    assert "514.2 km" in line
    # the same drive from a CSV is bounded by the file's size instead: not refused here
    data["trajectory"]["source"] = str(tmp_path / "t.csv")
    (tmp_path / "t.csv").write_text(STREET_CSV)
    assert run_cli("config", "show", config_file(tmp_path, data))[0] == 0


def test_aes_key_length_against_aes_key_bits(tmp_path):
    keys = tmp_path / "keys"
    generate_keys(keys, range(8), aes_bits=256)
    data = dict(TINY, security={"keys_dir": str(keys), "aes_key_bits": 128})
    line = assert_one_line(*check(tmp_path, data)[::2], str(key_paths(keys, 0)["aes"]))
    assert "aes_key_bits is 128" in line


def test_swapped_aes_and_hmac_files(tmp_path):
    keys = tmp_path / "keys"
    generate_keys(keys, range(8), aes_bits=256)  # both 32 bytes: only the label tells them apart
    p = key_paths(keys, 0)
    aes, mac = p["aes"].read_bytes(), p["hmac"].read_bytes()
    p["aes"].write_bytes(mac)
    p["hmac"].write_bytes(aes)
    data = dict(TINY, security={"keys_dir": str(keys), "aes_key_bits": 256})
    assert "swapped" in assert_one_line(*check(tmp_path, data)[::2], str(p["aes"]))


def test_key_file_of_another_bs(tmp_path):
    keys = tmp_path / "keys"
    generate_keys(keys, range(8))
    p0, p1 = key_paths(keys, 0), key_paths(keys, 1)
    p0["hmac"].write_bytes(p1["hmac"].read_bytes())
    with pytest.raises(InputError, match="bs1, expected bs0|'bs1', expected bs0"):
        load_keys(keys, [0])


def test_mesh_path_escaping_the_scene_folder(tmp_path):
    line = check_edited_scene_xml(tmp_path, "meshes/ground.ply", "../../../../etc/passwd")
    assert "outside the scene's folder" in line


def test_no_bs_reaching_the_ue_warns(caplog):
    from veriloc_rt.sim.checks import warn_unreachable

    with caplog.at_level(logging.WARNING):
        assert warn_unreachable(np.zeros((5, 3), bool)) == 5
    assert [r.getMessage() for r in caplog.records][0].startswith(
        "no serving BS reaches the UE at any of the 5 points")
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        assert warn_unreachable(np.eye(5, 3, dtype=bool)) == 2   # rows 3 and 4 have no link
    # counted by hand: points 3 and 4 of 5, 2 / 5 = 40.0 %
    assert "at 2 of the 5 points (40.0 %)" in caplog.records[0].getMessage()
    caplog.clear()
    with caplog.at_level(logging.WARNING):   # one link a point is enough: no warning
        assert warn_unreachable(np.eye(5, 3, k=0, dtype=bool)[[0, 1, 2, 0, 1]]) == 0
    assert not caplog.records


def test_csv_with_a_utf8_byte_order_mark(tmp_path):
    code, out, err = check(tmp_path, csv_config(tmp_path, "\ufeff" + STREET_CSV))
    assert code == 0, err
    assert out.startswith("ok: 6 points")


# --- messages ----------------------------------------------------------------------------------

@pytest.mark.parametrize("args, field", [
    (["run", "--points", "many"], "--points"),
    (["frobnicate"], "command"),
    (["scene"], "--out"),
    (["run", "--no-such-flag"], "--no-such-flag"),
    (["config", "print"], "action"),
])
def test_argparse_errors_are_one_line(args, field):
    line = assert_one_line(*run_cli(*args)[::2], field)
    assert "usage" not in line


def test_tracking_field_named_with_its_prefix(tmp_path):
    data = dict(TINY, detectors={"tracking": {"accept_m": 3}})
    assert_one_line(*check(tmp_path, data)[::2], "detectors.tracking.accept_m")


def test_nan_vertex_is_named_as_such(tmp_path):
    scene = external_scene(tmp_path)
    ply = scene / "meshes" / "ground.ply"
    _box_ply(ply, vertices=np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0], [0, 0, 1.0]]))
    line = assert_one_line(*check(tmp_path, external_config(tmp_path, scene))[::2], str(ply))
    assert "vertex 2 is not finite" in line


def test_missing_public_key_message(tmp_path):
    keys = tmp_path / "keys"
    generate_keys(keys, range(8))
    pub = key_paths(keys, 0)["verify"]
    pub.unlink()
    line = assert_one_line(*check(tmp_path, dict(TINY, security={"keys_dir": str(keys)}))[::2],
                           str(pub))
    assert line == f"error: {pub}: missing key file (generate a set with `veriloc-rt keys --out DIR`)"


def test_line_break_in_a_file_name_stays_one_line(tmp_path):
    f = tmp_path / "a\nb.json"
    f.write_text("{")
    assert_one_line(*run_cli("config", "show", f)[::2], str(f))


def test_bs_height_at_the_schemas_old_minimum(tmp_path):
    # 1 m was the schema's minimum; the UMa model (and `compare`, whatever the model) then
    # stopped with "ValueError: antenna heights (z) must be > 1 m", exit 1
    code, _, err = check(tmp_path, dict(TINY, topology={"bs_height_m": 1}))
    assert_one_line(code, err, "topology.bs_height_m")


def test_trajectory_z_below_1m(tmp_path):
    text = "t,x,y,z\n0,0,0,1.5\n1,0,5,0.5\n2,0,10,1.5\n"
    code, _, err = check(tmp_path, csv_config(tmp_path, text))
    assert "z = 0.5 m" in assert_one_line(code, err, f"{tmp_path / 't.csv'}:3")
