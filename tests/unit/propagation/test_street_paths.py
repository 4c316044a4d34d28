"""Exhaustive edge-diffraction candidates (veriloc_rt.propagation.street_paths).

Independent references: Fermat's principle (the diffraction point makes the path length
stationary, found here by Brent's root of its slope); the reflection chains a ray can follow
between two facing walls and the ground; the image method for a wall reflection; and Sionna
RT's own shoot-and-bounce candidates at a high ray count, whose paths the exhaustive candidates
must contain with the same coefficients (same image method and field calculator, another way
to find the candidate).
"""

import itertools

import numpy as np
import pytest
from scipy.optimize import brentq

from veriloc_rt.config import RayTracingConfig
from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.propagation import street_paths as sp
from veriloc_rt.propagation.link_metrics import SAME_PATH_TOL_S

from .rt_scenes import boxes, ground, write_test_scene

FC = 3.5e9
#: float64 closed form against Brent's root of the path-length slope (xtol 1e-12 m)
KELLER_TOL_M = 1e-6
#: float32 delays of the image method: ~1e-14 s; 1 ps is 0.3 mm of path length
DELAY_TOL_S = 1e-12
#: one path computed twice by the same float32 field calculator: equal to float32 rounding
SAME_PATH_POWER_TOL_DB = 0.01


def test_keller_point_minimises_the_path_length():
    rng = np.random.default_rng(3)
    for _ in range(50):
        s, t, a = rng.normal(size=(3, 3)) * [30.0, 30.0, 10.0]
        e = rng.normal(size=3)
        e /= np.linalg.norm(e)
        x = sp.keller_point(s, t, a, e)

        def slope(u):     # d(path length)/du: zero at the stationary (Fermat) point
            p = a + u * e
            return (np.dot(p - s, e) / np.linalg.norm(p - s)
                    - np.dot(t - p, e) / np.linalg.norm(t - p))
        ref = brentq(slope, -1e4, 1e4, xtol=1e-12)
        assert abs(x - ref) < KELLER_TOL_M


def test_matrix_keller_equals_the_pointwise_one():
    rng = np.random.default_rng(4)
    S, T = rng.normal(size=(2, 7, 3)) * 40.0
    a = rng.normal(size=(11, 3)) * 40.0
    e = rng.normal(size=(11, 3))
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    n = rng.normal(size=(11, 2, 3))
    x, _ = sp.keller_on_edges(S, T, a, e, np.full(11, 1e3), n)
    ref = sp.keller_point(S[:, None], T[:, None], a[None], e[None])
    np.testing.assert_allclose(x, ref, atol=KELLER_TOL_M)


def test_edge_frames_broadcast_to_the_keller_points_of_every_pair():
    """The ends' edge frames, computed once per end and broadcast (source chains x target
    chains x edges), give every pair's Keller point (the pointwise closed form) and the same
    bits as the row-by-row matrix form."""
    rng = np.random.default_rng(5)
    S, T = rng.normal(size=(4, 3)) * 40.0, rng.normal(size=(5, 3)) * 40.0
    a = rng.normal(size=(9, 3)) * 40.0
    e = rng.normal(size=(9, 3))
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    n = rng.normal(size=(9, 2, 3))
    length = np.full(9, 1e3)
    fs, ft = sp.edge_frame(S, a, e, n), sp.edge_frame(T, a, e, n)
    x, ok = sp.keller_from_frames([f[:, None] for f in fs], [f[None] for f in ft], length)
    ref = sp.keller_point(S[:, None, None], T[None, :, None], a[None, None], e[None, None])
    np.testing.assert_allclose(x, ref, atol=KELLER_TOL_M)
    qs, qt = np.repeat(np.arange(4), 5), np.tile(np.arange(5), 4)
    x_rows, ok_rows = sp.keller_from_frames([f[qs] for f in fs], [f[qt] for f in ft], length)
    np.testing.assert_array_equal(x.reshape(20, 9), x_rows)
    np.testing.assert_array_equal(ok.reshape(20, 9), ok_rows)


def test_hopeless_candidates_have_no_reflection_point():
    """The wall y = 2.5 facing -y; the source (0, 0, 1.5) in front of it, its image (0, 5, 1.5)
    behind it. A diffraction point p has a reflection point on the wall exactly when the line
    from the image to p crosses y = 2.5 between them: at t = (5 - 2.5) / (5 - p_y) in (0, 1).
    Beyond REFLECTION_SIDE_MARGIN_M on either side, hopeless is exactly 'no crossing'; within
    it (and without a reflection) never."""
    geo = _street_geometry()
    wall = next(k for k in range(geo.num_planes) if geo.plane_n[k][1] < -0.5)
    img = np.array([0.0, 5.0, 1.5])
    rng = np.random.default_rng(6)
    p = np.column_stack([rng.uniform(-40, 40, 400), rng.uniform(-10, 15, 400),
                         rng.uniform(0, 20, 400)])
    p = p[np.abs(p[:, 1] - 2.5) > sp.REFLECTION_SIDE_MARGIN_M]
    with np.errstate(divide="ignore"):
        t = (5.0 - 2.5) / (5.0 - p[:, 1])
    crossing = (t > 0) & (t < 1)
    got = sp.hopeless(geo, np.full(len(p), wall), np.repeat(img[None], len(p), axis=0), p)
    np.testing.assert_array_equal(got, ~crossing)
    assert got.any() and (~got).any()
    # just behind the wall (within the margin), or no reflection at all: never hopeless
    near = np.array([[3.0, 2.5 + 0.5 * sp.REFLECTION_SIDE_MARGIN_M, 15.0], [3.0, 8.0, 15.0]])
    assert not sp.hopeless(geo, np.array([wall, -1]), np.repeat(img[None], 2, axis=0),
                           near).any()


def _street_geometry() -> sp.SceneGeometry:
    """Two facing walls 5 m apart (y = -2.5 facing +y, y = 2.5 facing -y) and the ground."""
    v = np.array([[-50, -2.5, 0], [50, -2.5, 0], [50, -2.5, 15], [-50, -2.5, 15],
                  [-50, 2.5, 0], [50, 2.5, 0], [50, 2.5, 15], [-50, 2.5, 15],
                  [-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]], float)
    f = np.array([[0, 2, 1], [0, 3, 2],          # normal +y
                  [4, 5, 6], [4, 6, 7],          # normal -y
                  [8, 9, 10], [8, 10, 11]])      # ground, +z
    return sp.SceneGeometry.from_meshes([(1, v, f)])


def test_near_planes_keeps_the_nearest_faces_when_there_are_many():
    """Twenty small square plates (1 m, facing +x), plate k on the plane x = k (all 20 within
    30 m of the origin's plane distance) but offset along y by 40 - 2k: the distance from the
    origin to plate k's face is the hypotenuse sqrt(dx^2 + dy^2) of its nearest point, computed
    here in closed form. With more than MAX_NEAR_PLANES planes in reach, the ones kept are the
    MAX_NEAR_PLANES nearest by that distance, not by the planes' own distance (k)."""
    verts, faces = [], []
    for k in range(20):
        x, y0 = float(k), 40.0 - 2.0 * k
        base = len(verts)
        verts += [[x, y0, 0.0], [x, y0 + 1.0, 0.0], [x, y0 + 1.0, 1.0], [x, y0, 1.0]]
        faces += [[base, base + 1, base + 2], [base, base + 2, base + 3]]   # normal +x
    geo = sp.SceneGeometry.from_meshes([(1, np.array(verts), np.array(faces))])
    assert geo.num_planes == 20
    origin = np.zeros(3)
    # nearest point of plate k: (k, clamp(0, y0, y0 + 1), 0)
    y0 = 40.0 - 2.0 * np.arange(20)
    dist = np.hypot(np.arange(20.0), np.clip(0.0, y0, y0 + 1.0))
    want = np.argsort(dist, kind="stable")[:sp.MAX_NEAR_PLANES]
    got = sp.near_planes(geo, origin, 30.0)
    x_of_plane = geo.plane_d * geo.plane_n[:, 0]          # plane x = d (normal +x)
    assert sorted(np.round(x_of_plane[got]).astype(int)) == sorted(want.tolist())
    # few planes in reach: every one, as before (the plane distance alone)
    assert len(sp.near_planes(geo, origin, 5.5)) == 6


def test_reflection_chains_alternate_between_reachable_planes():
    geo = _street_geometry()
    assert geo.num_planes == 3
    src = np.array([0.0, 0.5, 1.5])
    planes = sp.near_planes(geo, src, 20.0)
    seqs, imgs = sp.sequences(geo, src, planes, 3)
    wall_lo = next(p for p in planes if geo.plane_n[p][1] > 0.5)
    wall_hi = next(p for p in planes if geo.plane_n[p][1] < -0.5)
    ground_ = next(p for p in planes if geo.plane_n[p][2] > 0.5)
    # what a ray can do: a wall sends it towards the other wall (walls alternate), walls keep
    # its vertical direction, so after the ground (down -> up) it never meets the ground again
    expected = set()
    for k in range(4):
        for q in itertools.product((wall_lo, wall_hi, ground_), repeat=k):
            walls = [p for p in q if p != ground_]
            if all(a != b for a, b in zip(walls, walls[1:])) and q.count(ground_) <= 1 and \
                    all(a != b for a, b in zip(q, q[1:])):
                expected.add(q)
    assert {tuple(int(p) for p in row if p >= 0) for row in seqs} == expected
    assert len(seqs) == len(expected) == 1 + 3 + 6 + 8
    # the image in the wall y = -2.5 and then in y = 2.5: y -> -5 - y -> 10 + y
    k = next(i for i, q in enumerate(seqs) if list(q) == [wall_lo, wall_hi, -1])
    np.testing.assert_allclose(imgs[k], [0.0, 10.5, 1.5], atol=1e-12)


def test_near_wedges_are_the_used_planes_edges_within_reach():
    """A 10 x 10 x 15 m block: 8 wedges (4 vertical, 4 roof; the bottom edges stand on the
    ground). Its face x = 0 has three (two vertical edges and a roof edge); from (-3, 5, 1.5)
    the vertical edges are sqrt(3^2 + 5^2) = 5.83 m away, the roof edge sqrt(3^2 + 13.5^2) =
    13.83 m."""
    import trimesh

    box = trimesh.creation.box(extents=(10.0, 10.0, 15.0))
    box.apply_translation((5.0, 5.0, 7.5))
    geo = sp.SceneGeometry.from_meshes([(1, box.vertices, box.faces)])
    assert geo.num_wedges == 8
    face = int(np.flatnonzero((geo.plane_n[:, 0] < -0.99) & (np.abs(geo.plane_d) < 1e-9))[0])
    p = np.array([-3.0, 5.0, 1.5])
    seq = np.array([[face, -1], [-1, -1]])

    def kinds(w):
        return sorted("roof" if abs(geo.edge_a[i, 2] - geo.edge_b[i, 2]) < 1e-9 else "vertical"
                      for i in w)
    assert kinds(geo.near_wedges(p, seq, 5.8)) == []
    assert kinds(geo.near_wedges(p, seq, 5.9)) == ["vertical", "vertical"]
    assert kinds(geo.near_wedges(p, seq, 13.9)) == ["roof", "vertical", "vertical"]
    assert len(geo.near_wedges(p, np.full((1, 2), -1), 1e3)) == 0   # no plane used


def test_duplicates_keep_the_first_copy_only():
    tau = np.array([[1e-6, 1e-6 + 5e-13, 1e-6 + 2e-11, 1e-6]])
    angles = np.zeros((1, 4, 4))
    inter = np.array([[[8, 0], [8, 0], [8, 0], [1, 8]]], np.uint8)
    valid = np.ones((1, 4), bool)
    dup = sp.duplicates(tau, angles, inter, valid)
    # path 1 repeats path 0 (delay within 1 ps); path 2 is 20 ps away; path 3 another sequence
    assert dup.tolist() == [[False, True, False, False]]


def test_duplicates_equal_the_pairwise_definition():
    """The sorted search against every pair compared (a copy: same sequence, delays within the
    tolerance, four angles within theirs, both valid; every copy after the first flagged), on
    random links whose delays sit on a grid of 0.75 tolerances (chains of near delays)."""
    rng = np.random.default_rng(5)
    tol = SAME_PATH_TOL_S
    for _ in range(200):
        links, paths = rng.integers(1, 5), rng.integers(1, 25)
        tau = 1e-6 + rng.integers(0, 5, (links, paths)) * 0.75 * tol
        angles = rng.integers(0, 2, (links, paths, 4)) * 0.7 * sp.SAME_ANGLE_RAD
        inter = rng.integers(0, 2, (links, paths, 2)).astype(np.uint8)
        valid = rng.random((links, paths)) < 0.8
        same = np.abs(tau[:, :, None] - tau[:, None, :]) <= tol
        same &= np.all(np.abs(angles[:, :, None] - angles[:, None, :]) <= sp.SAME_ANGLE_RAD, -1)
        same &= np.all(inter[:, :, None] == inter[:, None, :], axis=-1)
        same &= valid[:, :, None] & valid[:, None, :]
        want = np.any(same & np.tril(np.ones((paths, paths), bool), k=-1), axis=-1)
        assert np.array_equal(sp.duplicates(tau, angles, inter, valid), want)


@pytest.mark.raytrace
def test_exhaustive_candidates_contain_the_sampled_diffraction_paths(tmp_path):
    """A 5 m street between two 15 m buildings; the UE in it, the BS above the roofs 150 m off.

    Every diffracted path that Sionna's own candidates find with 1e6 rays is among the
    exhaustive ones with the same coefficient, the exhaustive candidates find at least as many,
    and the roof-edge path has the delay of the Keller construction.
    """
    from veriloc_rt.propagation.sionna_rt import SionnaTracer

    meshes = {"ground": ground(400.0),
              "b": boxes([[-60, 2.5, 40, 32.5], [-60, -32.5, 40, -2.5]], [15.0, 15.0])}
    tracer = SionnaTracer(write_test_scene(tmp_path, meshes), FC, seed=1)
    ue = np.array([[0.0, 0.7, 1.5]])
    bs = np.array([[20.0, 150.0, 25.0]])
    sampled = tracer.trace(ue, bs, RayTracingConfig(edge_candidates="sampled", rays_per_source=10**6))
    exh = tracer.trace(ue, bs, RayTracingConfig(edge_candidates="exhaustive", rays_per_source=10**3))
    diffracted = sampled.valid[0] & np.any(sampled.interactions[0] == 8, axis=-1)
    assert diffracted.sum() >= 3
    p_s = np.sum(np.abs(sampled.a[0]) ** 2, axis=(1, 2))
    p_e = np.sum(np.abs(exh.a[0]) ** 2, axis=(1, 2))
    for k in np.flatnonzero(diffracted):
        same = exh.valid[0] & (np.abs(exh.tau[0] - sampled.tau[0, k]) < DELAY_TOL_S) & \
            np.all(exh.interactions[0] == sampled.interactions[0, k], axis=-1)
        assert same.sum() == 1, f"sampled path {k} ({sampled.interactions[0, k]}) not found"
        j = np.flatnonzero(same)[0]
        assert abs(10 * np.log10(p_e[j] / p_s[k])) < SAME_PATH_POWER_TOL_DB
    assert np.sum(exh.valid[0] & np.any(exh.interactions[0] == 8, axis=-1)) >= diffracted.sum()
    # the path over the near roof edge (y = 2.5, z = 15) alone: Keller point on that line
    a, e = np.array([0.0, 2.5, 15.0]), np.array([1.0, 0.0, 0.0])
    p = a + sp.keller_point(ue[0], bs[0], a, e) * e
    tau = (np.linalg.norm(p - ue[0]) + np.linalg.norm(bs[0] - p)) / SPEED_OF_LIGHT
    d_only = exh.valid[0] & (exh.interactions[0, :, 0] == 8) & (exh.interactions[0, :, 1] == 0)
    assert np.min(np.abs(exh.tau[0][d_only] - tau)) < DELAY_TOL_S


@pytest.mark.raytrace
def test_hopeless_candidates_are_rejected_by_the_image_method(tmp_path, monkeypatch):
    """The street of the test above, the UE traced to the BS and to a second street-level end:
    handing the hopeless candidates to Sionna's image method as well yields more candidates and
    exactly the same paths (it rejects every one of them)."""
    from veriloc_rt.propagation.sionna_rt import SionnaTracer

    meshes = {"ground": ground(400.0),
              "b": boxes([[-60, 2.5, 40, 32.5], [-60, -32.5, 40, -2.5]], [15.0, 15.0])}
    tracer = SionnaTracer(write_test_scene(tmp_path, meshes), FC, seed=1)
    ue = np.array([[0.0, 0.7, 1.5]])
    ends = np.array([[20.0, 150.0, 25.0], [35.0, -0.8, 1.5]])
    fid = RayTracingConfig(edge_candidates="exhaustive", rays_per_source=10**3)
    kept = tracer.trace(ue, ends, fid)
    n_kept = tracer.last_num_edge_candidates
    monkeypatch.setattr(sp, "hopeless", lambda geo, plane, img, p: np.zeros(len(p), bool))
    every = tracer.trace(ue, ends, fid)
    assert tracer.last_num_edge_candidates > n_kept
    for f in kept.FIELDS:
        np.testing.assert_array_equal(getattr(kept, f), getattr(every, f))


def test_aligned_copies_start_on_the_jit_alignment():
    """Dr.Jit compiles its loads for the alignment of an aliased NumPy buffer: the copies
    handed to it start on a JIT_ALIGNMENT boundary, with the values, shape and type asked."""
    from veriloc_rt.propagation.street_paths import JIT_ALIGNMENT, aligned

    rng = np.random.default_rng(0)
    for n in (1, 3, 17, 1000):
        x = rng.normal(size=(n, 3))[:, 1]              # a strided view
        for dtype in (np.float32, np.uint32, np.float64):
            y = aligned(x, dtype)
            assert y.ctypes.data % JIT_ALIGNMENT == 0 and y.flags.c_contiguous
            assert y.dtype == dtype and np.array_equal(y, x.astype(dtype))
    z = aligned(np.arange(12.0).reshape(4, 3))
    assert z.shape == (4, 3) and z.ctypes.data % JIT_ALIGNMENT == 0
