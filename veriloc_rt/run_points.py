"""One scenario over the trajectory: chain calls, the five detectors and the outcome per point.

:class:`ScenarioRunner` is configured once per run (config, geometry, propagation, keys) and
called per scenario; it yields one :class:`PointRow` per trajectory point, which the engine
writes to the scenario's CSV as soon as it exists.

Per point ``i`` and PRS mode (standard; encrypted when ``run.evaluate_encrypted``):

1. the adversary transmits only in the attack window (``run.attack_points``) and only in an
   attack scenario; its grid comes from :class:`~veriloc_rt.run_adversary.AdversarySignal`;
2. the chain runs with the noise stream ``stream(seed, "noise", mode, i)``, the same in every
   scenario (common random numbers: a benign point gives the same chain result in every
   scenario, so it is computed once per run and reused); the adversary's own draws come from
   ``stream(seed, "adversary", scenario, mode, i)``;
3. detectors (standard PRS only, as the paper evaluates them):

   * HMAC: :class:`TagDetector` on the chain's tag checks (``security.tag_scheme`` should be
     'hmac'); DigSig: the same rule on a second, DS-tagged chain call with the same noise and
     adversary draws (``run.digsig='separate'``; it keeps the first call's timing and decodes
     its own tags: ``PositioningChain(estimates=...)``), or on the HMAC run's checks ('shared');
   * ABSA: the AoA per BS, resolved against and compared with the azimuth from the *last
     validated position* (the Kalman tracker's position after its last accepted fix; before the
     first one, the current DL fix);
   * Handshake: DL fix against UL fix; Tracking: the Kalman tracker on the DL fix.

4. outcome: ``success`` (fix ok and horizontal error <= ``run.success_threshold_m``),
   ``large_error`` (fix ok, error above), ``service_failure`` (no fix: fewer than 3 BSs heard or
   the solver failed).

Resume: the tracker (the only state) is rebuilt by replaying the saved rows' DL fixes
(:meth:`ScenarioRunner.replay`); the CSV stores them at full float precision, so the replay is
exact and a resumed run ends with the same rows as an uninterrupted one.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from dataclasses import dataclass

import numpy as np

from .config import Config
from .detectors import ABSADetector, HandshakeDetector, KalmanTracker, TagDetector
from .receiver.chain import STAGES, ChainResult, PositioningChain
from .rng import stream
from .run_adversary import AdversarySignal

log = logging.getLogger(__name__)

__all__ = ["PointRow", "ScenarioRunner", "LocalChains", "DETECTORS", "OUTCOMES", "outcome_of"]

DETECTORS = ("HMAC", "DigSig", "ABSA", "Handshake", "Tracking")
OUTCOMES = ("success", "large_error", "service_failure")


@dataclass
class PointRow:
    """One trajectory point of one scenario (a CSV row).

    time_s : float, s; verdicts : {detector: bool} (True valid); attack : bool
    true_xy, est_xy : [2] float64, m (est NaN without a fix); error_m : float (NaN without a fix)
    outcome : str; the ``*_enc`` fields: the same for encrypted PRS (None when not evaluated)
    """

    index: int
    time_s: float
    attack: bool
    verdicts: dict
    true_xy: np.ndarray
    est_xy: np.ndarray
    error_m: float
    outcome: str
    est_xy_enc: np.ndarray | None = None
    error_m_enc: float | None = None
    outcome_enc: str | None = None


def outcome_of(fix_ok: bool, error_m: float, threshold_m: float) -> str:
    """'success', 'large_error' or 'service_failure' (paper Fig. "encrypted_PRS")."""
    if not fix_ok:
        return "service_failure"
    return "success" if error_m <= threshold_m else "large_error"


class ScenarioRunner:
    """Chains, adversary and detectors of one run.

    :param cfg: run config; geometry, propagation: from the engine; keys: by BS id
    """

    def __init__(self, cfg: Config, geometry, propagation, keys):
        self.cfg, self.geo, self.prop = cfg, geometry, propagation
        self.window = cfg.run.attack_points(geometry.num_points)
        nbs = cfg.nr.num_bs
        mk = dict(nr=cfg.nr, channel=cfg.channel, ue_array=cfg.propagation.ue_array,
                  carrier_frequency_hz=cfg.propagation.carrier_frequency_hz, keys=keys)
        sec = cfg.security
        self.chains = {"standard": PositioningChain(security=sec, receiver=cfg.receiver, **mk)}
        if cfg.run.evaluate_encrypted:  # outcomes only: no uplink, AoA or tag check needed
            enc = dataclasses.replace(sec, encrypted=(True,) * nbs)
            rx = dataclasses.replace(cfg.receiver, uplink=False)
            self.chains["encrypted"] = PositioningChain(security=enc, receiver=rx, fix_only=True, **mk)
        self.ds_chain = None
        if cfg.run.digsig == "separate" and sec.tag_scheme != "ds":
            ds = dataclasses.replace(sec, tag_scheme="ds")
            rx = dataclasses.replace(cfg.receiver, uplink=False)
            self.ds_chain = PositioningChain(security=ds, receiver=rx, **mk)
        self.adversary = {m: AdversarySignal(cfg, c) for m, c in self.chains.items()}
        if self.ds_chain is not None:
            self.adversary["ds"] = AdversarySignal(cfg, self.ds_chain)
        d = cfg.detectors
        self.hmac, self.digsig = TagDetector(d.hmac), TagDetector(d.digsig)
        self.absa, self.handshake = ABSADetector(d.absa), HandshakeDetector(d.handshake)
        self.tracker = KalmanTracker(d.tracking)
        #: chain results by cache key: (key, i) benign, shared by the scenarios (common random
        #: numbers); (key, scenario, i) attack points computed by a worker, used once
        self._benign: dict[tuple, ChainResult] = {}
        #: seconds: adversary signals, chain calls (total and by stage, :data:`STAGES`), detectors
        self.timing = {"adversary": 0.0, "chain": 0.0, **dict.fromkeys(STAGES, 0.0), "detectors": 0.0}
        self._last_valid: np.ndarray | None = None

    # -- state -------------------------------------------------------------------------------
    def reset(self) -> None:
        """Fresh detector state for a new scenario."""
        self.tracker.reset()
        self._last_valid = None

    def _track(self, est_xy: np.ndarray, dt: float | None) -> bool:
        z = est_xy if np.all(np.isfinite(est_xy)) else None
        v = self.tracker(z, dt)
        if v.accepted:
            self._last_valid = v.position.copy()
        return v.valid

    def replay(self, rows: list[PointRow]) -> None:
        """Rebuild the detector state from saved rows (resume)."""
        self.reset()
        prev = None
        for r in rows:
            self._track(r.est_xy, self._dt(prev, r.index))
            prev = r.index

    def _dt(self, prev: int | None, i: int) -> float | None:
        if prev is None:
            return None
        t = self.geo.ue.t
        return float(t[i] - t[prev]) if t[i] > t[prev] else None

    # -- per point ---------------------------------------------------------------------------
    # -- chain results, local or from worker processes --------------------------------------
    def _keys(self) -> list[tuple[str, PositioningChain, int]]:
        out = [("standard", self.chains["standard"], 0)]
        if self.ds_chain is not None:
            out.append(("ds", self.ds_chain, 0))
        if "encrypted" in self.chains:
            out.append(("encrypted", self.chains["encrypted"], 1))
        return out

    def _ck(self, key: str, scenario: str, i: int) -> tuple:
        attack = scenario != "none" and bool(self.window[i])
        return (key, scenario, i) if attack else (key, i)

    def needs_chains(self, scenario: str, i: int) -> bool:
        """Whether point ``i`` of ``scenario`` still needs chain calls (not cached)."""
        return any(self._ck(k, scenario, i) not in self._benign for k, _, _ in self._keys())

    def compute_chains(self, scenario: str, i: int) -> dict:
        """Every chain result point ``i`` of ``scenario`` needs, by cache key (for workers);
        in the attack window also those of the run's later attack scenarios, computed here
        together: they share the serving BSs' signal, noise and uplink, which each chain keeps
        from one call to the next (:meth:`PositioningChain._benign`). The engine holds them
        until their scenario comes."""
        out: dict = {}
        for sc in self._scenarios_at(scenario, i):
            for k, c, m in self._keys():   # 'standard' first: the DS chain reuses its timing
                ck = self._ck(k, sc, i)
                if ck in out or (sc != scenario and ck in self._benign):
                    continue
                std = out.get(self._ck("standard", sc, i)) if k == "ds" else None
                out[ck] = self._chain(k, c, sc, m, i, std)
        return out

    def _scenarios_at(self, scenario: str, i: int) -> list[str]:
        """The scenarios :meth:`compute_chains` evaluates at point ``i`` of ``scenario``."""
        out = [scenario]
        if self.window[i] and scenario in self.cfg.run.scenarios:
            later = self.cfg.run.scenarios[self.cfg.run.scenarios.index(scenario) + 1:]
            out += [s for s in later if s != "none"]
        return out

    def chain_work(self, scenario: str, i: int) -> int:
        """How many scenarios' chains point ``i`` of ``scenario`` still computes (for progress)."""
        return sum(any(self._ck(k, sc, i) not in self._benign for k, _, _ in self._keys())
                   for sc in self._scenarios_at(scenario, i))

    def store_chains(self, results: dict) -> None:
        """Results from :meth:`compute_chains` (run elsewhere) for the next :meth:`point` calls."""
        self._benign.update(results)

    def _chain(self, key: str, chain: PositioningChain, scenario: str, mode: int, i: int,
               estimates: ChainResult | None = None) -> ChainResult:
        attack = scenario != "none" and bool(self.window[i])
        ck = self._ck(key, scenario, i)
        if ck in self._benign:
            # benign results are shared by every scenario; attack results come from workers
            return self._benign[ck] if not attack else self._benign.pop(ck)
        p = self.prop
        sig = None
        if attack:
            t = time.perf_counter()
            sig = self.adversary[key](scenario, i, i, p.bs_ue, p.bs_adv, self.geo.adversary.pos[i],
                                      self.geo.ue.pos[i], stream(self.cfg.seed, "adversary",
                                                                 _SCEN[scenario], mode, i),
                                      adv_ue=p.adv_ue)
            self.timing["adversary"] += time.perf_counter() - t
        t = time.perf_counter()
        before = dict(chain.stage_s)
        res = chain(p.bs_ue, i, stream(self.cfg.seed, "noise", mode, i), frame=i,
                    adv_ue=p.adv_ue if attack else None, adversary_signal=sig, estimates=estimates)
        self.timing["chain"] += time.perf_counter() - t
        for k in STAGES:
            self.timing[k] += chain.stage_s[k] - before[k]
        if not attack:
            self._benign[ck] = res
        return res

    def point(self, scenario: str, i: int, prev: int | None) -> PointRow:
        """Evaluate point ``i`` of ``scenario`` (``prev``: the previous evaluated point)."""
        cfg = self.cfg
        true_xy = self.geo.ue.pos[i, :2]
        res = self._chain("standard", self.chains["standard"], scenario, 0, i)
        est, err, out = self._fix(res, true_xy)
        ds = self._chain("ds", self.ds_chain, scenario, 0, i, res) if self.ds_chain is not None else res
        t = time.perf_counter()
        v = {"HMAC": self.hmac(res.tags_valid, res.detected).valid,
             "DigSig": self.digsig(ds.tags_valid, ds.detected).valid}
        bs_pos = self.prop.bs_ue.tx_pos[i]
        ref = self._last_valid if self._last_valid is not None else (est if np.all(np.isfinite(est)) else None)
        ref_az = self.absa.reference_azimuth(bs_pos, ref)
        # no AoA: NaN; no reference: unresolvable, and ABSA does not check that BS anyway
        az = np.array([float(a.resolve(r)[0]) if (a is not None and np.isfinite(r)) else np.nan
                       for a, r in zip(res.aoa, ref_az)])
        v["ABSA"] = self.absa(az, bs_pos, reference_position=ref).valid
        ul = res.uplink.position if res.uplink is not None else None
        v["Handshake"] = self.handshake(res.position.position if res.position.ok else None,
                                        ul.position if (ul is not None and ul.ok) else None).valid
        v["Tracking"] = self._track(est, self._dt(prev, i))
        self.timing["detectors"] += time.perf_counter() - t
        row = PointRow(i, float(self.geo.ue.t[i]), scenario != "none" and bool(self.window[i]),
                       v, true_xy.copy(), est, err, out)
        if "encrypted" in self.chains:
            r2 = self._chain("encrypted", self.chains["encrypted"], scenario, 1, i)
            row.est_xy_enc, row.error_m_enc, row.outcome_enc = self._fix(r2, true_xy)
        return row

    def _fix(self, res: ChainResult, true_xy: np.ndarray) -> tuple[np.ndarray, float, str]:
        if not res.position.ok:
            return np.full(2, np.nan), float("nan"), "service_failure"
        est = np.asarray(res.position.position[:2], dtype=float).copy()
        err = float(np.linalg.norm(est - true_xy))
        return est, err, outcome_of(True, err, self.cfg.run.success_threshold_m)


_SCEN = {"none": 0, "fbs": 1, "meaconing": 2, "jamming": 3}


# -- executors: where the chains of the points ahead are computed ------------------------------
# The detectors carry state from point to point, so they run in order in the engine's process;
# the chains of the points ahead are independent (every draw comes from a named stream per
# point) and go to an executor. ``imap(scenario, points)`` yields ``(i, results, timing)`` for
# every point, in order, with ``results`` for :meth:`ScenarioRunner.store_chains`; the numbers
# are the serial run's whatever the executor.

#: the runner a forked worker process uses (set by :class:`ForkPool` before forking)
_WORKER: ScenarioRunner | None = None


def _chains_of(runner: ScenarioRunner, scenario: str, i: int) -> tuple[int, dict, dict]:
    before = dict(runner.timing)
    res = runner.compute_chains(scenario, i)
    runner._benign.clear()  # the engine's runner keeps the cache; a worker only computes
    return i, res, {k: runner.timing[k] - before[k] for k in before}


def _work(task: tuple[str, int]) -> tuple[int, dict, dict]:
    scenario, i = task
    return _chains_of(_WORKER, scenario, i)


class LocalChains:
    """The chains computed in this process, ahead of the detectors like a pool's (so a point's
    attack scenarios share its serving BSs' signal here too: :meth:`ScenarioRunner.compute_chains`)."""

    def __init__(self, runner: ScenarioRunner):
        self.runner = runner

    def imap(self, scenario: str, points: list[int]):
        for i in points:   # the runner's own timing counts them
            yield i, self.runner.compute_chains(scenario, i), {}

    def close(self) -> None:
        pass

    terminate = close


class ForkPool:
    """``workers`` forked processes computing :meth:`ScenarioRunner.compute_chains`.

    Forked, so the workers inherit the runner (keys included) without pickling it.
    """

    def __init__(self, runner: ScenarioRunner, workers: int):
        import multiprocessing as mp

        global _WORKER
        _WORKER = runner
        self.pool = mp.get_context("fork").Pool(workers, initializer=_ignore_sigint)

    def imap(self, scenario: str, points: list[int]):
        return self.pool.imap(_work, [(scenario, i) for i in points], chunksize=2)

    def close(self) -> None:
        self.pool.close()
        self.pool.join()

    def terminate(self) -> None:
        self.pool.terminate()


def _ignore_sigint() -> None:
    """Workers leave Ctrl-C to the parent, which terminates them and keeps the finished rows."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


#: on a Dask worker: the runners of the runs it computes chunks for, by (token, thread id)
_DASK_RUNNERS: dict[tuple[str, int], ScenarioRunner] = {}
_DASK_LOCK = threading.Lock()


def _dask_chunk(token: str, spec: tuple, scenario: str, points: list[int]) -> list[tuple]:
    """A Dask task: the chains of ``points`` (a trajectory chunk).

    The runner is built once per worker thread (a runner is not thread-safe) from
    ``spec = (cfg, geometry, propagation)``; the keys are rebuilt from the config, as the
    Ed25519 key objects do not pickle.
    """
    k = (token, threading.get_ident())
    with _DASK_LOCK:
        runner = _DASK_RUNNERS.get(k)
    if runner is None:
        from .engine import run_keys

        cfg, geometry, prop = spec
        runner = ScenarioRunner(cfg, geometry, prop, run_keys(cfg, len(geometry.bs_pos)))
        with _DASK_LOCK:
            _DASK_RUNNERS[k] = runner
    return [_chains_of(runner, scenario, i) for i in points]


def _dask_forget(token: str) -> int:
    """On every worker when a run ends: drop its runners (and with them its propagation)."""
    with _DASK_LOCK:
        keys = [k for k in _DASK_RUNNERS if k[0] == token]
        for k in keys:
            del _DASK_RUNNERS[k]
    return len(keys)


class DaskChains:
    """Trajectory chunks as tasks on a Dask cluster (a connected ``distributed.Client``).

    The run's config, geometry and propagation go to every worker once; each chunk of
    ``chunk`` points is one task; at most two chunks per worker thread (plus one) are in
    flight, so results never pile up on the cluster ahead of the detectors.

    :param chunk: points per task (None: about four tasks per worker thread, 1 to 16 points)
    """

    def __init__(self, runner: ScenarioRunner, client, chunk: int | None = None):
        import uuid

        self.client, self.chunk = client, chunk
        self.token = f"veriloc-chains-{uuid.uuid4().hex}"
        self.threads = max(1, sum(client.nthreads().values()))
        [self.spec] = client.scatter([(runner.cfg, runner.geo, runner.prop)], broadcast=True,
                                     hash=False)
        self.inflight: set = set()
        log.info("Dask: %d worker threads at %s", self.threads, client.scheduler.address)

    def imap(self, scenario: str, points: list[int]):
        from collections import deque

        size = self.chunk or max(1, min(16, -(-len(points) // (4 * self.threads))))
        chunks = [points[k:k + size] for k in range(0, len(points), size)]
        pending: deque = deque()
        nxt = 0
        while pending or nxt < len(chunks):
            while nxt < len(chunks) and len(pending) < 2 * self.threads + 1:
                f = self.client.submit(_dask_chunk, self.token, self.spec, scenario,
                                       chunks[nxt], key=f"{self.token}-{scenario}-{nxt}",
                                       pure=False)
                pending.append(f)
                self.inflight.add(f)
                nxt += 1
            f = pending.popleft()
            out = f.result()
            self.inflight.discard(f)
            yield from out

    def close(self) -> None:
        """Release the run's data on the cluster (the client stays connected)."""
        for f in self.inflight:
            f.cancel()
        self.inflight.clear()
        if self.spec is None:  # closed already
            return
        self.spec.release()
        self.spec = None
        try:
            self.client.run(_dask_forget, self.token)
        except Exception as exc:  # noqa: BLE001 - a worker gone by now has nothing to forget
            log.warning("Dask: could not clear the workers' runners (%s)", exc)

    terminate = close
