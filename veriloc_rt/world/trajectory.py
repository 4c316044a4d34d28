"""UE trajectories (street-following generator or CSV) and the adversary that follows them.

A trajectory is sampled at fixed times but stored with its path (a polyline) and the arc
length at each sample, so the adversary can follow *the same path* a number of points behind.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config import TrajectoryConfig
from ..config.world import MIN_ANTENNA_HEIGHT_M
from ..errors import InputError, bad_value, short_repr
from ..inputs import numeric_csv, read_text

_DIRS = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])  # E, N, W, S
_TURN_SPEED = 4.0  # m/s through a corner (about 15 km/h)
_DS = 0.25  # m, arc-length step of the kinematic integration
_STOP_LINE = 6.0  # m before the intersection centre where a stopping vehicle waits
_BEND_WINDOW_M = 5.0  # m, a graph route's heading at a vertex is taken over this distance
#: largest trajectory CSV read, bytes (a million points of t,x,y,z at full precision: ~80 MB)
MAX_CSV_BYTES = 128 << 20


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A sampled path.

    t : [num_points] float64, s; pos : [num_points, 3] float64, m; vel : [num_points, 3] m/s
    s : [num_points] float64, m (arc length along ``path``)
    path : [num_vertices, 3] float64, m (polyline the samples lie on)
    """

    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    s: np.ndarray
    path: np.ndarray

    @property
    def num_points(self) -> int:
        return len(self.t)

    def head(self, n: int) -> "Trajectory":
        return Trajectory(self.t[:n], self.pos[:n], self.vel[:n], self.s[:n], self.path)

    def at_arclength(self, s: np.ndarray) -> np.ndarray:
        """Positions at arc lengths ``s`` [m]; before the start, extend the first segment back."""
        seg = np.diff(self.path, axis=0)
        seg_len = np.linalg.norm(seg, axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg_len)])
        s = np.asarray(s, dtype=float)
        out = np.stack([np.interp(s, cum, self.path[:, i]) for i in range(3)], axis=-1)
        before = s < 0
        if np.any(before):
            first = np.argmax(seg_len > 0)
            d = seg[first] / seg_len[first]
            out[before] = self.path[0] + s[before, None] * d
        return out

    def densified_xy(self, step: float = 2.0) -> np.ndarray:
        """Points along the covered part of the path at most ``step`` apart. -> [n, 2]"""
        s = np.arange(min(self.s.min(), 0.0), self.s.max() + step, step)
        return self.at_arclength(s)[:, :2]


def follower(ue: Trajectory, lag_points: int, min_separation: float) -> Trajectory:
    """The adversary: on the UE's exact path, ``lag_points`` samples behind, never closer than
    ``min_separation`` along the path (it queues behind a stopped UE). Before the UE's first
    sample it waits behind the start on the first street."""
    k = np.arange(ue.num_points)
    lagged = np.where(k >= lag_points, ue.s[np.maximum(k - lag_points, 0)], ue.s[0] - min_separation)
    s_adv = np.minimum(lagged, ue.s - min_separation)
    pos = ue.at_arclength(s_adv)
    pos[:, 2] = ue.pos[:, 2]
    vel = _velocity(ue.t, pos)
    return Trajectory(ue.t.copy(), pos, vel, s_adv, ue.path)


def _velocity(t: np.ndarray, pos: np.ndarray) -> np.ndarray:
    if len(t) < 2:
        return np.zeros_like(pos)
    return np.gradient(pos, t, axis=0)


def generate_street_trajectory(cfg: TrajectoryConfig, canyon, rng: np.random.Generator) -> Trajectory:
    """Drive along the canyon's street centre lines.

    Route: from the intersection nearest the origin, at each intersection go straight or turn
    (``turn_probability``), staying inside ``region_m``. Speed: a cruise speed per block drawn in
    [min_speed, max_speed], at most 4 m/s through turns, full stops (``stop_probability``, dwell
    up to ``max_stop_s``) at the stop line 6 m before an intersection, acceleration and braking
    limited to ``accel_mps2``.
    """
    pitch = canyon.pitch
    nodes = canyon.street_nodes(cfg.region_m)
    if len(nodes) < 4:
        raise bad_value("trajectory.region_m", cfg.region_m,
                        f"a region holding at least 2x2 intersections (block pitch {pitch} m)")
    lim = np.abs(nodes).max()
    total_time = (cfg.num_points - 1) * cfg.dt_s
    need = total_time * cfg.max_speed_mps + 2 * pitch
    # --- route: a sequence of intersections ------------------------------------------------
    cur = np.zeros(2)
    heading = int(rng.integers(4))
    route = [cur.copy()]
    turns = [False]
    length = 0.0
    while length < need:
        options = []
        if rng.uniform() < cfg.turn_probability:
            options = [(heading + 1) % 4, (heading + 3) % 4]
            rng.shuffle(options)
        options += [heading, (heading + 1) % 4, (heading + 3) % 4, (heading + 2) % 4]
        for h in options:
            nxt = cur + pitch * _DIRS[h]
            if np.all(np.abs(nxt) <= lim + 1e-6):
                break
        turns[-1] = h != heading and len(route) > 1
        heading, cur = h, nxt
        route.append(cur.copy())
        turns.append(False)
        length += pitch
    route = np.array(route)
    # --- speed limit along the arc length ----------------------------------------------------
    n_nodes = len(route)
    s_grid = np.arange(0.0, (n_nodes - 1) * pitch + _DS / 2, _DS)
    cruise = rng.uniform(cfg.min_speed_mps, cfg.max_speed_mps, n_nodes - 1)
    cruise = np.maximum(cruise, 0.5)
    vmax = cruise[np.minimum((s_grid // pitch).astype(int), n_nodes - 2)]
    stops = rng.uniform(size=n_nodes) < cfg.stop_probability
    stops[0] = True
    dwell = np.where(stops, rng.uniform(1.0, max(cfg.max_stop_s, 1.0), n_nodes), 0.0)
    dwell[0] = 0.0
    node_idx = np.round(np.arange(n_nodes) * pitch / _DS).astype(int)
    node_idx = np.minimum(node_idx, len(s_grid) - 1)
    vmax[node_idx[np.array(turns)]] = np.minimum(vmax[node_idx[np.array(turns)]], _TURN_SPEED)
    # a stopping vehicle waits at the stop line, short of the intersection (not at the start)
    stop_idx = node_idx.copy()
    stop_idx[1:] = np.maximum(node_idx[1:] - int(round(_STOP_LINE / _DS)), 0)
    vmax[stop_idx[stops]] = 0.0
    # acceleration limits: forward then backward pass on v^2
    v = _accel_limited(vmax, cfg.accel_mps2)
    vmid = np.maximum(0.5 * (v[1:] + v[:-1]), 1e-3)
    dt_steps = _DS / vmid
    # dwell times are added on arrival at a stop node
    arrive_dwell = np.zeros(len(s_grid))
    arrive_dwell[stop_idx[stops]] = dwell[stops]
    t_grid = np.concatenate([[0.0], np.cumsum(dt_steps)]) + np.cumsum(arrive_dwell)
    # time -> arc length: during a dwell t advances while s stays (duplicate s entries)
    t_aug = np.concatenate([t_grid - arrive_dwell, t_grid])
    s_aug = np.concatenate([s_grid, s_grid])
    order = np.lexsort((s_aug, t_aug))
    t_aug, s_aug = t_aug[order], s_aug[order]
    t = np.arange(cfg.num_points) * cfg.dt_s
    if t[-1] > t_aug[-1]:
        raise RuntimeError("route too short for the requested duration")  # need covers this
    s = np.interp(t, t_aug, s_aug)
    path = np.concatenate([route, np.full((n_nodes, 1), cfg.ue_height_m)], axis=1)
    traj = Trajectory(t, np.zeros((len(t), 3)), np.zeros((len(t), 3)), s, path)
    pos = traj.at_arclength(s)
    return Trajectory(t, pos, _velocity(t, pos), s, path)


def generate_graph_trajectory(cfg: TrajectoryConfig, graph, rng: np.random.Generator) -> Trajectory:
    """Drive along the edges of a street graph (:class:`~veriloc_rt.world.streets.StreetGraph`)
    with the canyon generator's kinematics.

    Route: from the node nearest the origin along a random edge (the UE's first point lies
    ``adversary_min_separation_m`` along it, so the adversary starts on the route); at each node go straight (the
    edge whose start heading is closest to the arrival heading) or, with ``turn_probability``,
    take one of the other edges at random; a dead end turns back. Speed: a cruise speed per edge
    drawn in [min_speed, max_speed], at most 4 m/s through a change of heading over 30 degrees
    (at nodes and at an edge's bends), a full stop to turn back at a dead end, full stops
    (``stop_probability``, dwell up to ``max_stop_s``) at junctions of three or more streets, on
    the stop line 6 m before the junction (or halfway along a shorter edge), acceleration and
    braking limited to ``accel_mps2``.

    :raises InputError: if the graph has no street
    """
    if not len(graph.edges):
        raise InputError("trajectory.source", "the street graph has no street to drive along")
    nbrs = graph.neighbours()
    deg = np.array([len(n) for n in nbrs])
    total_time = (cfg.num_points - 1) * cfg.dt_s
    # the UE starts adversary_min_separation_m into the route, so that the adversary waiting
    # behind it (:func:`follower`) stands on the route too
    lead = cfg.adversary_min_separation_m
    need = total_time * cfg.max_speed_mps + lead + 50.0
    cur = int(np.argmin(np.where(deg > 0, np.linalg.norm(graph.nodes, axis=1), np.inf)))
    e, nxt = nbrs[cur][int(rng.integers(len(nbrs[cur])))]
    pieces, node_kind, length = [], [], 0.0   # node_kind: 0 pass, 1 junction, 2 dead end
    while True:
        poly = graph.polylines[e] if int(graph.edges[e, 0]) == cur else graph.polylines[e][::-1]
        pieces.append(poly)
        length += float(np.linalg.norm(np.diff(poly, axis=0), axis=1).sum())
        cur = nxt
        if length >= need:
            break
        heading = poly[-1] - poly[-2]
        options = [(oe, on) for oe, on in nbrs[cur] if oe != e]
        if not options:
            node_kind.append(2)
            e, nxt = e, int(graph.edges[e, 0] if graph.edges[e, 1] == cur else graph.edges[e, 1])
            continue
        node_kind.append(1 if deg[cur] >= 3 else 0)
        turn = [_turn_angle(heading, _start_dir(graph, oe, cur)) for oe, _ in options]
        order = np.argsort(turn, kind="stable")
        pick = int(order[0])
        if len(options) > 1 and rng.uniform() < cfg.turn_probability:
            pick = int(order[1 + rng.integers(len(options) - 1)])
        e, nxt = options[pick]
    # --- route polyline, node arc lengths, speed limits --------------------------------------
    route = [pieces[0]] + [p[1:] for p in pieces[1:]]
    ends = np.cumsum([len(p) - (0 if k == 0 else 1) for k, p in enumerate(pieces)]) - 1
    route = np.concatenate(route)
    seg = np.linalg.norm(np.diff(route, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-9])
    vertex_s = np.concatenate([[0.0], np.cumsum(seg)])
    node_s = vertex_s[ends[:-1]]                     # the nodes between edges
    route, vertex_s = route[keep], vertex_s[keep]
    s_grid = np.arange(0.0, vertex_s[-1] + _DS / 2, _DS)
    cruise = np.maximum(rng.uniform(cfg.min_speed_mps, cfg.max_speed_mps, len(pieces)), 0.5)
    edge_of = np.searchsorted(node_s, s_grid, side="right")
    vmax = cruise[edge_of]
    # bends: heading change over 30 degrees at an interior vertex, the headings taken over
    # _BEND_WINDOW_M before and after it (a derived centre line's raster steps are no bends)
    sv = vertex_s[1:-1]
    at = [np.stack([np.interp(x, vertex_s, route[:, i]) for i in range(2)], -1)
          for x in (sv - _BEND_WINDOW_M, sv, sv + _BEND_WINDOW_M)]
    d0, d1 = at[1] - at[0], at[2] - at[1]
    ang = np.abs(np.arctan2(d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0], np.sum(d0 * d1, axis=1)))
    bend_s = sv[ang > np.deg2rad(30.0)]
    bend_idx = np.minimum(np.round(bend_s / _DS).astype(int), len(s_grid) - 1)
    vmax[bend_idx] = np.minimum(vmax[bend_idx], _TURN_SPEED)
    kind = np.array(node_kind, dtype=int)
    n_idx = np.minimum(np.round(node_s / _DS).astype(int), len(s_grid) - 1)
    vmax[n_idx[kind == 2]] = 0.0
    stops = (rng.uniform(size=len(node_s)) < cfg.stop_probability) & (kind == 1)
    dwell = np.where(stops, rng.uniform(1.0, max(cfg.max_stop_s, 1.0), len(node_s)), 0.0)
    prev_s = np.concatenate([[0.0], node_s[:-1]])
    stop_s = np.maximum(node_s - np.minimum(_STOP_LINE, 0.5 * (node_s - prev_s)), 0.0)
    stop_idx = np.minimum(np.round(stop_s / _DS).astype(int), len(s_grid) - 1)
    vmax[stop_idx[stops]] = 0.0
    vmax[0] = 0.0   # the drive starts from standstill
    v = _accel_limited(vmax, cfg.accel_mps2)
    dt_steps = _DS / np.maximum(0.5 * (v[1:] + v[:-1]), 1e-3)
    arrive_dwell = np.zeros(len(s_grid))
    np.add.at(arrive_dwell, stop_idx[stops], dwell[stops])
    t_grid = np.concatenate([[0.0], np.cumsum(dt_steps)]) + np.cumsum(arrive_dwell)
    t_aug = np.concatenate([t_grid - arrive_dwell, t_grid])
    s_aug = np.concatenate([s_grid, s_grid])
    order = np.lexsort((s_aug, t_aug))
    t_aug, s_aug = t_aug[order], s_aug[order]
    t0 = float(np.interp(lead, s_grid, t_grid - arrive_dwell))
    t = np.arange(cfg.num_points) * cfg.dt_s
    if t0 + t[-1] > t_aug[-1]:
        raise InputError("trajectory.num_points", f"the street graph cannot hold a "
                         f"{t[-1]:g} s drive (its route ends after {t_aug[-1] - t0:.1f} s)")
    s = np.interp(t0 + t, t_aug, s_aug)
    path = np.concatenate([route, np.full((len(route), 1), cfg.ue_height_m)], axis=1)
    traj = Trajectory(t, np.zeros((len(t), 3)), np.zeros((len(t), 3)), s, path)
    pos = traj.at_arclength(s)
    return Trajectory(t, pos, _velocity(t, pos), s, path)


def _start_dir(graph, edge: int, node: int) -> np.ndarray:
    poly = graph.polylines[edge] if int(graph.edges[edge, 0]) == node else graph.polylines[edge][::-1]
    return poly[1] - poly[0]


def _turn_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Unsigned angle between two directions, rad."""
    return float(abs(math.atan2(a[0] * b[1] - a[1] * b[0], float(np.dot(a, b)))))


def _accel_limited(vmax: np.ndarray, accel: float) -> np.ndarray:
    """The fastest speed profile [n] m/s under the caps ``vmax`` [n] m/s (every _DS m) that
    accelerates and brakes at most ``accel`` m/s^2: a forward, then a backward pass on v^2
    (v^2 grows by at most 2 a ds per step)."""
    v2 = vmax ** 2
    for i in range(1, len(v2)):
        v2[i] = min(v2[i], v2[i - 1] + 2 * accel * _DS)
    for i in range(len(v2) - 2, -1, -1):
        v2[i] = min(v2[i], v2[i + 1] + 2 * accel * _DS)
    return np.sqrt(v2)


def load_csv_trajectory(path: str | Path, cfg: TrajectoryConfig) -> Trajectory:
    """Read ``t,x,y[,z]`` (header row required; z defaults to ``ue_height_m``).

    :raises InputError: naming the file, row and column for anything unusable
    """
    field = "trajectory.source"
    text = read_text(path, field, "trajectory file", MAX_CSV_BYTES)
    path = Path(path)
    _, rows = numeric_csv(text, str(path), (["t", "x", "y"], ["t", "x", "y", "z"]),
                          "'t,x,y' or 't,x,y,z'")
    rows_used = [i for i, _ in rows]   # the values' line numbers
    data = [vals for _, vals in rows]
    if len(data) < 2:
        raise InputError(str(path), f"{len(data)} data rows, expected at least 2")
    arr = np.array(data)[: cfg.num_points]
    t = arr[:, 0]
    if np.any(np.diff(t) <= 0):
        bad = int(np.argmax(np.diff(t) <= 0)) + 1
        raise InputError(f"{path}:{rows_used[bad]}", "time t must increase strictly")
    z = arr[:, 3] if arr.shape[1] == 4 else np.full(len(t), cfg.ue_height_m)
    if np.any(z <= MIN_ANTENNA_HEIGHT_M):
        bad = int(np.argmax(z <= MIN_ANTENNA_HEIGHT_M))
        raise InputError(f"{path}:{rows_used[bad]}", f"z = {z[bad]:g} m, expected a UE height "
                         f"above {MIN_ANTENNA_HEIGHT_M:g} m (TR 38.901's h_E, which the UMa model "
                         "and `compare` need)")
    pos = np.stack([arr[:, 1], arr[:, 2], z], axis=-1)
    with np.errstate(over="ignore", invalid="ignore"):  # huge values: checked just below
        step = np.linalg.norm(np.diff(pos, axis=0), axis=1)
        s = np.concatenate([[0.0], np.cumsum(step)])
        vel = _velocity(t, pos)
    if not np.all(np.isfinite(s)):
        raise InputError(str(path), "coordinates too large: the path length is not finite")
    if s[-1] <= 0.0:
        raise InputError(str(path), "the UE never moves (every row at one position); the "
                         "adversary follows the UE's path, so the trajectory must move")
    if not np.all(np.isfinite(vel)):
        bad = int(np.argmax(~np.all(np.isfinite(vel), axis=1)))
        raise InputError(f"{path}:{rows_used[bad]}", "the speed is not finite (time steps too "
                         "small for the distance covered)")
    keep = np.concatenate([[True], step > 0])  # polyline without repeated vertices
    return Trajectory(t, pos, vel, s, pos[keep])


def check_points(scene, pos: np.ndarray, what: str, source: str) -> None:
    """Reject points inside a building or outside the scene with one clear error.

    :param scene: an :class:`~veriloc_rt.world.scene.canyon.UrbanCanyon` or
        :class:`~veriloc_rt.world.scene.external.MeshScene`
    """
    pos = np.asarray(pos, dtype=float)
    outside = ~scene.inside_extent(pos[:, :2])
    if np.any(outside):
        k = int(np.argmax(outside))
        raise InputError(source, f"{what} point {k} at ({pos[k, 0]:.1f}, {pos[k, 1]:.1f}) m is "
                         "outside the scene")
    if hasattr(scene, "pitch"):
        inside = scene.inside_building(pos[:, :2]) & (pos[:, 2] < roof_height(scene, pos))
    else:
        inside = scene.inside_building(pos)
    if np.any(inside):
        k = int(np.argmax(inside))
        raise InputError(source, f"{what} point {k} at ({pos[k, 0]:.1f}, {pos[k, 1]:.1f}, "
                         f"{pos[k, 2]:.1f}) m is inside a building; points must lie in streets")


def roof_height(canyon, pos: np.ndarray) -> np.ndarray:
    """Roof height of the block under each point (0 in streets)."""
    fp = canyon.footprints
    h = np.zeros(len(pos))
    for start in range(0, len(pos), 1024):
        p = pos[start:start + 1024, None, :2]
        inside = ((p[..., 0] >= fp[:, 0]) & (p[..., 0] <= fp[:, 2])
                  & (p[..., 1] >= fp[:, 1]) & (p[..., 1] <= fp[:, 3]))
        h[start:start + 1024] = np.where(inside, canyon.heights, 0.0).max(axis=1, initial=0.0)
    return h
