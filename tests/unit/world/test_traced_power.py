"""topology.selection 'traced_power': the candidate sites of each point (those within
candidate_radius_m, and always the num_trps nearest), the num_trps strongest of them by received
power, the CIR slots taken for them, and the one-line errors of a bad set-up."""

import contextlib
import io
import json

import numpy as np
import pytest

from veriloc_rt.cli import main
from veriloc_rt.config import config_from_dict
from veriloc_rt.errors import InputError
from veriloc_rt.propagation.cir import CIR
from veriloc_rt.world.sites import candidate_sites, nearest_serving, strongest_serving


def _grid_sites(step=100.0, n=7):
    g = np.arange(n) * step
    x, y = np.meshgrid(g, g, indexing="ij")
    return np.stack([x.ravel(), y.ravel(), np.full(x.size, 10.0)], axis=1)


def test_strongest_differ_from_nearest_and_match_a_sort():
    # one point, 5 sites on a line at 10, 20, 30, 40, 50 m: fake powers make the 3rd and 5th
    # nearest the strongest (a far site in line of sight, the near ones around corners)
    sites = np.array([[10.0 * (k + 1), 0.0, 10.0] for k in range(5)])
    bs, serving, cand, used = candidate_sites(sites, np.array([[0.0, 0.0]]), 2, 1000.0)
    assert list(used) == [0, 1, 2, 3, 4] and list(cand[0]) == [0, 1, 2, 3, 4]
    assert list(serving[0]) == [0, 1]                      # provisional: the 2 nearest
    power = np.array([[1e-12, 3e-12, 5e-9, 0.0, 2e-10]])
    chosen, col = strongest_serving(cand, power, 2)
    # independent derivation: sort (power desc, candidate order asc) by hand
    ranked = sorted(range(5), key=lambda j: (-power[0, j], j))[:2]
    assert list(col[0]) == ranked == [2, 4]
    assert list(chosen[0]) == [2, 4]
    assert set(chosen[0]) != set(nearest_serving(sites, np.array([[0.0, 0.0]]), 2)[1][0])


def test_strongest_ignore_padding_and_break_ties_nearest_first():
    rng = np.random.default_rng(3)
    sites = _grid_sites()
    xy = rng.uniform(0.0, 600.0, (40, 2))
    bs, serving, cand, used = candidate_sites(sites, xy, 4, 150.0)
    power = rng.choice([0.0, 1e-10, 1e-9, 1e-8], size=cand.shape)   # many ties, many zeros
    chosen, col = strongest_serving(cand, power, 4)
    for k in range(len(xy)):
        valid = [j for j in range(cand.shape[1]) if cand[k, j] >= 0]
        ranked = sorted(valid, key=lambda j: (-power[k, j], j))[:4]
        assert list(col[k]) == ranked
        assert list(chosen[k]) == [cand[k, j] for j in ranked]
        assert len(set(chosen[k])) == 4                    # a padded slot is never chosen


@pytest.mark.parametrize("radius", [50.0, 150.0, 260.0, 5000.0])
def test_candidates_are_bounded_by_the_radius(radius):
    rng = np.random.default_rng(5)
    sites = _grid_sites()
    xy = rng.uniform(-50.0, 650.0, (30, 2))
    n = 3
    bs, serving, cand, used = candidate_sites(sites, xy, n, radius)
    assert np.array_equal(bs, sites[used])
    for k in range(len(xy)):
        d = np.hypot(*(sites[:, :2] - xy[k]).T)
        # brute force: the sites within the radius, or among the n nearest (stable by index)
        near = set(np.argsort(d, kind="stable")[:n])
        expect = {int(i) for i in range(len(sites)) if d[i] <= radius or i in near}
        got = [int(used[c]) for c in cand[k] if c >= 0]
        assert set(got) == expect and len(got) == len(expect)
        assert np.all(np.diff(d[got]) >= 0)                # nearest first
        assert [used[s] for s in serving[k]] == got[:n]    # the provisional set: the nearest
    # the traced links: one per (point, candidate), no more than the sites within the radius
    within = (np.hypot(xy[:, None, 0] - sites[None, :, 0], xy[:, None, 1] - sites[None, :, 1])
              <= radius).sum(axis=1)
    assert int((cand >= 0).sum()) == int(np.maximum(within, n).sum())


def test_take_slots_moves_every_field():
    rng = np.random.default_rng(2)
    P, C, A, N = 3, 4, 2, 5
    cir = CIR(delays=rng.uniform(1e-6, 2e-6, (P, C, N)),
              gains=rng.normal(size=(P, C, A, N)) + 1j * rng.normal(size=(P, C, A, N)),
              aoa_az=rng.normal(size=(P, C, N)), aoa_zen=rng.normal(size=(P, C, N)),
              aod_az=rng.normal(size=(P, C, N)), aod_zen=rng.normal(size=(P, C, N)),
              doppler=rng.normal(size=(P, C, N)),
              interactions=rng.integers(0, 4, (P, C, N, 2)).astype(np.uint8),
              valid=rng.random((P, C, N)) < 0.7, tx_index=np.arange(P * C).reshape(P, C),
              tx_pos=rng.normal(size=(P, C, 3)), rx_pos=rng.normal(size=(P, 3)),
              los=rng.random((P, C)) < 0.5, carrier_frequency=3.5e9)
    col = np.array([[2, 0], [3, 1], [1, 2]])
    ids = np.array([[7, 8], [9, 10], [11, 12]])
    out = cir.take_slots(col, ids)
    for k in range(P):
        for j in range(2):
            c = col[k, j]
            for name in ("delays", "gains", "aoa_az", "doppler", "interactions", "valid",
                         "tx_pos", "los"):
                assert np.array_equal(getattr(out, name)[k, j], getattr(cir, name)[k, c]), name
    assert np.array_equal(out.tx_index, ids) and np.array_equal(out.rx_pos, cir.rx_pos)


def _check(tmp_path, data):
    f = tmp_path / "c.json"
    f.write_text(json.dumps(data))
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["config", "check", str(f)])
    return code, err.getvalue()


@pytest.mark.parametrize("data, field, says", [
    ({"topology": {"selection": "traced_power", "num_trps": 6}}, "topology.selection",
     "topology.sites"),
    ({"topology": {"selection": "traced_power", "sites": "s.csv"},
      "propagation": {"model": "uma"}}, "topology.selection", "propagation.model"),
    ({"topology": {"selection": "loudest"}}, "topology.selection", "traced_power"),
    ({"topology": {"candidate_radius_m": 0.0}}, "topology.candidate_radius_m", ""),
])
def test_bad_selection_is_one_line(tmp_path, data, field, says):
    (tmp_path / "s.csv").write_text("x,y,z\n0,0,10\n100,0,10\n0,100,10\n")
    code, err = _check(tmp_path, data)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith(f"error: {field}: ") and "Traceback" not in err
    assert says in lines[0]


def test_traced_power_config_is_accepted(tmp_path):
    (tmp_path / "s.csv").write_text("x,y,z\n0,0,10\n100,0,10\n0,100,10\n")
    cfg = config_from_dict({"topology": {"selection": "traced_power",
                                         "sites": str(tmp_path / "s.csv")}})
    assert cfg.topology.selection == "traced_power" and not cfg.topology.uses_cell
    with pytest.raises(InputError):
        config_from_dict({"topology": {"selection": "traced_power"}})


class _FakeModel:
    """A propagation model whose BS -> UE power is a known function of (point, BS id): one
    path of power ``_power(k, b)``; it records its calls."""

    calls: list = []

    def __call__(self, geometry, cfg, seed, *, progress=None, cache_dir="default",
                 adversary_points=None, workers=1, ue_points=None):
        P, T = geometry.serving.shape
        on = np.ones(P, bool) if ue_points is None else ue_points
        type(self).calls.append((geometry.serving.copy(), np.array(adversary_points),
                                 np.array(on)))
        k = np.arange(P)[:, None]
        pw = np.where(on[:, None], _power(k, geometry.serving), 0.0)

        def cir(t, tx):
            return CIR(delays=np.ones((P, t, 1)) * 1e-6,
                       gains=np.sqrt(pw[:, :t, None, None]).astype(complex) if t == T
                       else np.ones((P, t, 1, 1), complex),
                       aoa_az=np.zeros((P, t, 1)), aoa_zen=np.zeros((P, t, 1)),
                       aod_az=np.zeros((P, t, 1)), aod_zen=np.zeros((P, t, 1)),
                       doppler=np.zeros((P, t, 1)),
                       interactions=np.zeros((P, t, 1, 1), np.uint8),
                       valid=(pw[:, :t, None] > 0) if t == T else np.ones((P, t, 1), bool),
                       tx_index=tx, tx_pos=np.zeros((P, t, 3)), rx_pos=np.zeros((P, 3)),
                       los=np.zeros((P, t), bool), carrier_frequency=3.5e9)

        from veriloc_rt.propagation.raytrace import Propagation
        return Propagation(bs_ue=cir(T, geometry.serving), bs_adv=cir(T, geometry.serving),
                           adv_ue=cir(1, np.zeros((P, 1), np.int64)),
                           stats={"links": int(on.sum()) * T, "calls": 1})


def _power(k, b):
    """Received power of BS id ``b`` at point ``k``: larger for odd ids, varying with k."""
    return 1e-9 * (1.0 + (b % 2) * 10.0) / (1.0 + ((b * 7 + k * 3) % 5))


def test_engine_measures_the_strongest_candidates(tmp_path, monkeypatch):
    from veriloc_rt.sim import engine
    from veriloc_rt.world.geometry import Geometry
    from veriloc_rt.world.trajectory import Trajectory

    sites = _grid_sites(step=80.0, n=6)
    csv = tmp_path / "s.csv"
    csv.write_text("x,y,z\n" + "".join(f"{x},{y},{z}\n" for x, y, z in sites))
    cfg = config_from_dict({"topology": {"selection": "traced_power", "sites": str(csv),
                                         "num_trps": 4, "candidate_radius_m": 130.0},
                            "propagation": {"model": "raytrace"},
                            "run": {"scenarios": ["none", "meaconing"]}})
    P = 12
    rng = np.random.default_rng(8)
    pos = np.concatenate([rng.uniform(0.0, 400.0, (P, 2)), np.full((P, 1), 1.5)], axis=1)
    ue = Trajectory(np.arange(P, dtype=float), pos, np.zeros((P, 3)), np.arange(P, dtype=float),
                    pos)
    bs, serving, cand, used = candidate_sites(sites, pos[:, :2], 4, 130.0)
    geo = Geometry(scene_xml=tmp_path / "x.xml", scene=None, full_canyon=None, layout=None,
                   bs_pos=bs, serving=serving, ue=ue, adversary=ue, candidates=cand)

    class _Registry:
        def get(self, name):
            assert name == "raytrace"
            return _FakeModel

    _FakeModel.calls = []
    monkeypatch.setattr(engine, "PROPAGATION_REGISTRY", _Registry())
    chosen, prop = engine.traced_power_serving(cfg, geo)
    for k in range(P):
        valid = [int(c) for c in cand[k] if c >= 0]
        expect = sorted(valid, key=lambda b: (-_power(k, b), valid.index(b)))[:4]
        assert list(chosen.serving[k]) == expect
    assert not np.array_equal(chosen.serving, serving)     # not merely the nearest
    assert np.array_equal(prop.bs_ue.tx_index, chosen.serving)
    # the measured links' power is the candidates' traced power, to float rounding (1e-12 rel)
    got = prop.bs_ue.path_power().sum(axis=-1)
    np.testing.assert_allclose(got, _power(np.arange(P)[:, None], chosen.serving), rtol=1e-12)
    (s1, adv1, ue1), (s2, adv2, ue2) = _FakeModel.calls
    assert s1.shape[1] == cand.shape[1] and not adv1.any() and ue1.all()   # candidates only
    assert np.array_equal(s2, chosen.serving) and not ue2.any()            # adversary only
    assert np.array_equal(adv2, cfg.run.attack_points(P))
    assert prop.stats["candidate_links"] == int((cand >= 0).sum())
    assert prop.stats["links"] == P * cand.shape[1] and prop.stats["calls"] == 2
    # every real candidate has a path in the fake model (its power is positive everywhere)
    per_point = (cand >= 0).sum(axis=1)
    assert prop.stats["candidates_with_path"] == [int(per_point.min()),
                                                  float(np.median(per_point)),
                                                  int(per_point.max())]
