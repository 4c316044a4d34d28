"""One scenario over the trajectory: chain calls, the five detectors and the outcome per point.

:class:`ScenarioRunner` is configured once per run (config, geometry, propagation, keys) and
called per scenario; it yields one :class:`PointRow` per trajectory point, which the engine
writes to the scenario's CSV as soon as it exists.

Per point ``i`` and PRS mode (standard; encrypted when ``run.evaluate_encrypted``):

1. the adversary transmits only in the attack window (``run.attack_points``) and only in an
   attack scenario; its grid comes from :class:`~veriloc_rt.attacks.adversary.AdversarySignal`;
2. every chain runs with the noise stream ``stream(seed, "noise", 0, i)``, the same in every
   scenario and for both PRS modes (common random numbers: a benign point gives the same chain
   result in every scenario, so it is computed once per run and reused, and the standard-PRS and
   encrypted-PRS chains receive one thermal noise, drawn once:
   :class:`~veriloc_rt.phy.noise.KeptWhiteNoise`); the adversary's own draws come from
   the threat's stream (``Threat.rng``: ``stream(seed, "adversary", k, mode, i)``, k 1, 2, 3 for
   fbs, meaconing, jamming);
3. detectors (standard PRS only, as the paper evaluates them):

   * HMAC: :class:`TagDetector` on the chain's tag checks (``security.tag_scheme`` should be
     'hmac'); DigSig: the same rule on a second, DS-tagged chain call with the same noise and
     adversary draws (``run.digsig='separate'``; it keeps the first call's timing and decodes
     its own tags: ``ChainPlan.tags_on(...)``), or on the HMAC run's checks ('shared');
   * ABSA: the AoA per BS, resolved against and compared with the azimuth from the *last
     validated position* (the Kalman tracker's position after its last accepted fix; before the
     first one, the current DL fix);
   * Handshake: DL fix against UL fix; Tracking: the Kalman tracker on the DL fix (the five
     registered in :mod:`~veriloc_rt.detectors.registry`), then the plug-in detectors named in
     ``detectors.extra``, each on the point's :class:`~veriloc_rt.detectors.registry.PointInput`.

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
import time
from dataclasses import dataclass

import numpy as np

from ..config import Config
from ..detectors.registry import DETECTOR_REGISTRY, Detector, PointInput, Tracking
from ..detectors.outcomes import DETECTORS, PointRow, outcome_of
from ..detectors.statistics import auth_share_verdict, integrity_verdict
from ..phy.chain import FIX_ONLY, FULL, STAGES, Adversary, ChainPlan, ChainResult, PositioningChain
from ..phy.channel import Links
from ..phy.chain.receiver import reference_trp
from ..phy.noise import KeptWhiteNoise
from ..constants import SPEED_OF_LIGHT
from ..rng import stream
from ..attacks.adversary import AdversarySignal
from ..attacks.threats import BENIGN, THREAT_REGISTRY
from ..report.link_budget import multipath_penalty_db, tag_margin_db

log = logging.getLogger(__name__)

__all__ = ["ChainKey", "ChainRole", "FRAME_OFFSETS", "ScenarioRunner", "channel_doppler_hz", "frame_offset"]


#: frame counters a run may use: the 32-bit counter of the AES-CTR counter block and the tags
#: (phy.security.encryption, phy.security.tags), less the longest trajectory
#: (trajectory.num_points)
FRAME_OFFSETS = 2**32 - 1_000_000


def frame_offset(cfg: Config) -> int:
    """Frame counter of the run's first point.

    With key files (``security.keys_dir``) the same keys serve many runs and Monte Carlo
    realisations, so each run starts its frame counter at an offset drawn from its seed (the
    named stream ``"frame-offset"``): two runs with different seeds use the same (key, counter
    block) pair only if their windows of frame counters overlap, probability about
    2 N / :data:`FRAME_OFFSETS` for N points (6e-7 for the paper's 1200). Runs with the same
    seed and config repeat the same frames and the same plaintext: their ciphertexts are equal,
    which reveals nothing new. Without key files every seed draws its own keys, so no key serves
    two seeds and the offset stays 0 (the default run's numbers are unchanged).
    """
    if cfg.security.keys_dir is None:
        return 0
    return int(stream(cfg.seed, "frame-offset").integers(0, FRAME_OFFSETS))


@dataclass(frozen=True)
class ChainKey:
    """A chain result of a run: the chain (:attr:`ChainRole.name`), the point and, for a point
    in an attack scenario's window, the scenario (None: benign, the same in every scenario:
    common random numbers)."""

    chain: str
    point: int
    scenario: str | None = None


@dataclass(frozen=True, eq=False)
class ChainRole:
    """One of a run's chains.

    name : 'standard' (HMAC tags, AoA, UL fix: every detector), 'ds' (the DS-tagged grid's
        tags on the standard call's timing) or 'encrypted' (encrypted PRS, outcomes only)
    chain : PositioningChain; prs_mode : int, 0 standard PRS, 1 encrypted (names the adversary's
        stream); plan : ChainPlan of its calls (the DS chain's is made per call, on
        the standard result); adversary : AdversarySignal for this chain's frames
    """

    name: str
    chain: PositioningChain
    prs_mode: int
    plan: ChainPlan
    adversary: AdversarySignal


def channel_doppler_hz(cfg: Config, propagation) -> float:
    """The largest |Doppler| the UE receives in a run, Hz: its BS -> UE paths' and, with an
    attack scenario, the adversary -> UE paths' plus, with meaconing, the relay's own receive
    Doppler (the relayed signal carries both shifts)."""
    d = propagation.bs_ue.max_doppler_hz()
    scenarios = set(cfg.run.scenarios) - {BENIGN}
    if scenarios:
        d = max(d, propagation.adv_ue.max_doppler_hz())
    if any(THREAT_REGISTRY.get(s).relays for s in scenarios):
        # a relay: per point, the extreme sums of a received and a sent shift
        rx, tx = propagation.bs_adv, propagation.adv_ue

        def extremes(c):   # [num_points] largest and smallest valid Doppler (-inf / inf: none)
            hi = np.where(c.valid, c.doppler, -np.inf).max(axis=(1, 2))
            lo = np.where(c.valid, c.doppler, np.inf).min(axis=(1, 2))
            return hi, lo

        (rh, rl), (th, tl) = extremes(rx), extremes(tx)
        both = np.isfinite(rh) & np.isfinite(th)
        if np.any(both):
            d = max(d, float(np.max(rh[both] + th[both])), float(-np.min(rl[both] + tl[both])))
    return d


class ScenarioRunner:
    """Chains, adversary and detectors of one run.

    :param cfg: run config; geometry, propagation: from the engine; keys: by BS id
    """

    def __init__(self, cfg: Config, geometry, propagation, keys):
        self.cfg, self.geo, self.prop = cfg, geometry, propagation
        self.window = cfg.run.attack_points(geometry.num_points)
        #: frame counter of point 0 (point i is frame frame0 + i): see :func:`frame_offset`
        self.frame0 = frame_offset(cfg)
        #: the run's chains by name, in the order a point computes them ('standard' first: the
        #: DS chain reuses its timing)
        self.roles: dict[str, ChainRole] = {}
        #: Hz, the largest |Doppler| the UE can receive in this run (:func:`channel_doppler_hz`)
        self.max_doppler_hz = channel_doppler_hz(cfg, propagation)
        #: Hz, the UE's Doppler scan half-range (``receiver.doppler_scan``)
        self.doppler_scan_hz = cfg.receiver.scanned_for(self.max_doppler_hz).doppler_max_hz
        log.info("Doppler scan +-%.0f Hz (fastest Doppler of the run's paths %.1f Hz)",
                 self.doppler_scan_hz, self.max_doppler_hz)
        #: the UE's thermal noise, one draw per point shared by the chains (see the module doc)
        noise = KeptWhiteNoise()
        #: the meaconer's noise, one draw per point and PRS mode shared by that mode's chains
        relay_noise = KeptWhiteNoise(1)
        for name, mode, plan, sec, rx in self._chain_configs(cfg):
            chain = PositioningChain.from_config(cfg, keys, max_doppler_hz=self.max_doppler_hz,
                                                 security=sec, receiver=rx, noise=noise)
            self.roles[name] = ChainRole(name, chain, mode, plan, AdversarySignal(cfg, chain, relay_noise))
        #: the detectors by name: the built-ins, then ``detectors.extra`` (their order)
        self.detectors: dict[str, Detector] = {
            name: DETECTOR_REGISTRY.get(name, f"detectors.extra[{k - len(DETECTORS)}]"
                                        ).from_config(cfg)
            for k, name in enumerate(DETECTORS + cfg.detectors.extra)}
        #: the stateful built-in: its last accepted position is ABSA's reference
        self.tracking: Tracking = self.detectors["Tracking"]
        #: chain results by key: benign ones shared by the scenarios (common random numbers);
        #: attack points computed by a worker, used once
        self._results: dict[ChainKey, ChainResult] = {}
        #: seconds: adversary signals, chain calls (total and by stage, :data:`STAGES`), detectors
        self.timing = {"adversary": 0.0, "chain": 0.0, **dict.fromkeys(STAGES, 0.0), "detectors": 0.0}
        #: the last adversary signal, by (scenario, PRS mode, point)
        self._adversary_kept: tuple = (None, None)

    @staticmethod
    def _chain_configs(cfg: Config) -> list[tuple]:
        """(name, PRS mode, plan, security, receiver) of each chain the run needs."""
        sec = cfg.security
        out = [("standard", 0, FULL, sec, cfg.receiver)]
        no_uplink = dataclasses.replace(cfg.receiver, uplink=False)
        if cfg.run.digsig == "separate" and sec.tag_scheme != "ds":
            out.append(("ds", 0, FULL, dataclasses.replace(sec, tag_scheme="ds"), no_uplink))
        if cfg.run.evaluate_encrypted:  # outcomes only: no uplink, AoA or tag check needed
            enc = dataclasses.replace(sec, encrypted=(True,) * cfg.nr.num_bs)
            out.append(("encrypted", 1, FIX_ONLY, enc, no_uplink))
        return out

    # -- state -------------------------------------------------------------------------------
    def reset(self) -> None:
        """Fresh detector state for a new scenario."""
        for d in self.detectors.values():
            d.reset()

    def replay(self, rows: list[PointRow]) -> None:
        """Rebuild the detector state from saved rows (resume)."""
        self.reset()
        prev = None
        for r in rows:
            dt = self._dt(prev, r.index)
            for d in self.detectors.values():
                d.replay(r, dt)
            prev = r.index

    def _dt(self, prev: int | None, i: int) -> float | None:
        if prev is None:
            return None
        t = self.geo.ue.t
        return float(t[i] - t[prev]) if t[i] > t[prev] else None

    # -- chain results, local or from worker processes --------------------------------------
    def _attack(self, scenario: str, i: int) -> bool:
        return scenario != BENIGN and bool(self.window[i])

    def key(self, chain: str, scenario: str, i: int) -> ChainKey:
        """The cache key of chain ``chain``'s result at point ``i`` of ``scenario``."""
        return ChainKey(chain, i, scenario if self._attack(scenario, i) else None)

    def needs_chains(self, scenario: str, i: int) -> bool:
        """Whether point ``i`` of ``scenario`` still needs chain calls (not cached)."""
        return any(self.key(k, scenario, i) not in self._results for k in self.roles)

    def compute_chains(self, scenario: str, i: int) -> dict[ChainKey, ChainResult]:
        """Every chain result point ``i`` of ``scenario`` needs, by cache key (for workers);
        in the attack window also those of the run's later attack scenarios, computed here
        together: they share the serving BSs' signal, noise and uplink, which each chain keeps
        from one call to the next (:class:`~veriloc_rt.phy.chain.downlink.KeptDraw`). The
        engine holds them until their scenario comes."""
        out: dict = {}
        for sc in self._scenarios_at(scenario, i):
            for k in self.roles:   # 'standard' first: the DS chain reuses its timing
                ck = self.key(k, sc, i)
                if ck in out or (sc != scenario and ck in self._results):
                    continue
                std = out.get(self.key("standard", sc, i)) if k == "ds" else None
                out[ck] = self.chain_result(k, sc, i, std)
        return out

    def _scenarios_at(self, scenario: str, i: int) -> list[str]:
        """The scenarios :meth:`compute_chains` evaluates at point ``i`` of ``scenario``."""
        out = [scenario]
        if self.window[i] and scenario in self.cfg.run.scenarios:
            later = self.cfg.run.scenarios[self.cfg.run.scenarios.index(scenario) + 1:]
            out += [s for s in later if s != BENIGN]
        return out

    def chain_work(self, scenario: str, i: int) -> int:
        """How many scenarios' chains point ``i`` of ``scenario`` still computes (for progress)."""
        return sum(any(self.key(k, sc, i) not in self._results for k in self.roles)
                   for sc in self._scenarios_at(scenario, i))

    def worker_chains(self, scenario: str, i: int) -> tuple[int, dict, dict]:
        """:meth:`compute_chains` in an executor's worker: ``(i, results, timing)``, the timing
        being this call's seconds by :attr:`timing` key. The worker keeps no cache (the engine's
        runner does, from :meth:`store_chains`)."""
        before = dict(self.timing)
        res = self.compute_chains(scenario, i)
        self.clear_cache()
        return i, res, {k: self.timing[k] - before[k] for k in before}

    def clear_cache(self) -> None:
        """Forget every cached chain result."""
        self._results.clear()

    def store_chains(self, results: dict[ChainKey, ChainResult]) -> None:
        """Results from :meth:`compute_chains` (run elsewhere) for the next :meth:`point` calls."""
        self._results.update(results)

    def chain_result(self, chain: str, scenario: str, i: int,
                     timing_from: ChainResult | None = None) -> ChainResult:
        """The result of the chain named ``chain`` (:attr:`roles`) at point ``i`` of
        ``scenario``; benign results come from and go to the cache (:meth:`clear_cache`), attack
        results are used once. ``timing_from``: the DS chain decodes its tags on the standard
        call's timing (``ChainPlan.tags_on``)."""
        role = self.roles[chain]
        attack = self._attack(scenario, i)
        ck = self.key(chain, scenario, i)
        if ck in self._results:
            # benign results are shared by every scenario; attack results come from workers
            return self._results[ck] if not attack else self._results.pop(ck)
        p = self.prop
        adversary = None
        if attack:
            t = time.thread_time()
            # a false BS's and a jammer's signals depend on the run's config and the adversary's
            # stream alone, not on the chain: chains of one PRS mode (standard, DS-tagged) share
            # them; a relay's depends on the chain's frames
            ak = (scenario, role.prs_mode, i)
            threat = THREAT_REGISTRY.get(scenario)
            if threat.shared_by_chains and self._adversary_kept[0] == ak:
                sig = self._adversary_kept[1]
            else:
                rng = threat.rng(self.cfg.seed, role.prs_mode, i)
                sig = role.adversary(scenario, i, self.frame0 + i, p.bs_ue, p.bs_adv,
                                     self.geo.adversary.pos[i], self.geo.ue.pos[i], rng, adv_ue=p.adv_ue)
                self._adversary_kept = (ak, sig)
            adversary = Adversary(p.adv_ue, sig)
            self.timing["adversary"] += time.thread_time() - t
        plan = role.plan if timing_from is None else ChainPlan.tags_on(timing_from)
        t = time.thread_time()
        before = dict(role.chain.stage_s)
        res = role.chain(p.bs_ue, i, stream(self.cfg.seed, "noise", 0, i),
                         frame=self.frame0 + i, adversary=adversary, plan=plan)
        self.timing["chain"] += time.thread_time() - t
        for k in STAGES:
            self.timing[k] += role.chain.stage_s[k] - before[k]
        if not attack:
            self._results[ck] = res
        return res

    # -- per point ---------------------------------------------------------------------------
    def point(self, scenario: str, i: int, prev: int | None) -> PointRow:
        """Evaluate point ``i`` of ``scenario`` (``prev``: the previous evaluated point)."""
        true_xy = self.geo.ue.pos[i, :2]
        res = self.chain_result("standard", scenario, i)
        est, err, out = self._fix(res, true_xy)
        ds = self.chain_result("ds", scenario, i, res) if "ds" in self.roles else res
        t = time.thread_time()
        last = self.tracking.last_valid
        ref = last if last is not None else (est if np.all(np.isfinite(est)) else None)
        cov = res.position.covariance if res.position.ok else None
        x = PointInput(i, float(self.geo.ue.t[i]), res, ds, self.prop.bs_ue.tx_pos[i], ref, est,
                       cov, self._dt(prev, i))
        v = {name: det(x) for name, det in self.detectors.items()}
        self.timing["detectors"] += time.thread_time() - t
        row = PointRow(i, float(self.geo.ue.t[i]), self._attack(scenario, i),
                       {d: ok for d, (ok, _) in v.items()}, true_xy.copy(), est, err, out,
                       stats={d: st for d, (_, st) in v.items()})
        row.trps, row.links = trp_links(res, self.roles["standard"].chain, self.prop.bs_ue, i,
                                        self.geo.ue.pos[i],
                                        multipath_penalty_db(self.cfg.propagation))
        row.fix_cov = cov
        if self.cfg.trp_outputs:
            row.auth = authenticated_fix(res, self.roles["standard"].chain, self.prop.bs_ue, i)
            extra = {"Integrity": integrity_verdict(res.position,
                                                    self.cfg.receiver.integrity_false_alarm),
                     "AuthShare": auth_share_verdict(row.auth[0],
                                                     self.cfg.detectors.min_auth_share)}
            row.verdicts.update({d: ok for d, (ok, _) in extra.items()})
            row.stats.update({d: st for d, (_, st) in extra.items()})
        if "encrypted" in self.roles:
            r2 = self.chain_result("encrypted", scenario, i)
            row.est_xy_enc, row.error_m_enc, row.outcome_enc = self._fix(r2, true_xy)
        return row

    def _fix(self, res: ChainResult, true_xy: np.ndarray) -> tuple[np.ndarray, float, str]:
        if not res.position.ok:
            return np.full(2, np.nan), float("nan"), "service_failure"
        est = np.asarray(res.position.position[:2], dtype=float).copy()
        err = float(np.linalg.norm(est - true_xy))
        return est, err, outcome_of(True, err, self.cfg.run.success_threshold_m)


def authenticated_fix(res: ChainResult, chain: PositioningChain, bs_ue, i: int
                      ) -> tuple[float, np.ndarray]:
    """Per-anchor authentication (the OSNMA idea: authenticate each satellite, fix from the
    authenticated ones): the share of the DL fix's TRPs whose tags verified (NaN without a fix
    or without tags), and the fix from the heard TRPs whose tags verified alone ([2] NaN when
    it fails or no tags were checked), by the chain's own fix stage."""
    fix = res.position
    verified = np.asarray(res.detected, bool) & np.asarray(res.tags_valid, bool)
    used = list(fix.used) if fix.ok else []
    share = (float(np.mean(verified[used])) if used and res.tags_checked else float("nan"))
    xy = np.full(2, np.nan)
    if res.tags_checked and verified.sum() >= 3:
        auth = chain.fix.solve(verified, res.toa_s, res.peak_snr_db, bs_ue.tx_pos[i],
                               float(bs_ue.rx_pos[i, 2]))
        if auth.ok:
            xy = np.asarray(auth.position[:2], dtype=float)
    return share, xy


def trp_links(res: ChainResult, chain: PositioningChain, bs_ue, i: int,
              ue_pos: np.ndarray, penalty_db: float) -> tuple[tuple, list]:
    """What the row and the links CSV say about each TRP of point ``i``.

    Received PRS power: the TRP's transmit power (after power control) times the link's power
    gain (paths summed, antennas averaged). SNR per RE: that power's share of one PRS RE
    (``channel.prs_power``) over the noise per RE. ToA error: c toa - the 3-D distance (the
    receiver's timing reference is the earliest true arrival less a guard, so its ToAs are
    absolute); RSTD error: ToA error minus the fix reference's (empty for the reference);
    AoA error: the resolved azimuth minus the true direction, wrapped to (-180, 180] deg;
    peak SNR: the correlation peak's post-integration SNR the fix weights by (heard TRPs);
    HMAC and DS margins: the tags' margin against their decoding threshold measured on the
    waveform bench, after combining the UE's antennas
    (:func:`~veriloc_rt.report.link_budget.tag_margin_db`, less ``penalty_db``).

    :returns: ((bs_heard, bs_used, bs_excluded), [per TRP: LINK_COLUMNS after ``index``])
    """
    pos = bs_ue.tx_pos[i]
    dist = np.linalg.norm(pos - ue_pos[None, :], axis=1)
    rx_w = np.asarray(res.tx_power_w, float) * Links.from_cir(bs_ue, i).power_gain()
    with np.errstate(divide="ignore"):
        rx_dbm = 10.0 * np.log10(rx_w) + 30.0
        per_re = rx_w * chain.bs_power_factor * chain.ofdm.fft_size / chain.ofdm.num_subcarriers
        snr_db = (10.0 * np.log10(per_re / chain.noise_var) if chain.noise_var > 0
                  else np.full(len(pos), np.inf))
    toa_err = np.where(res.detected, SPEED_OF_LIGHT * res.toa_s - dist, np.nan)
    ref = reference_trp(res.detected, res.peak_snr_db)
    rstd_err = toa_err - toa_err[ref]
    rstd_err[ref] = np.nan
    true_az = np.arctan2(pos[:, 1] - ue_pos[1], pos[:, 0] - ue_pos[0])
    aoa_err = np.rad2deg(np.angle(np.exp(1j * (np.asarray(res.azimuth, float) - true_az))))
    fix = res.position
    used = set(fix.used) if fix.ok else set()
    excluded = tuple(int(j) for j in fix.excluded)
    antennas = len(chain.element_pos)
    margin = {s: tag_margin_db(snr_db, antennas, s, penalty_db) for s in ("hmac", "ds")}
    links = [(k, int(bs_ue.tx_index[i, k]), float(dist[k]), float(rx_dbm[k]), float(snr_db[k]),
              bool(res.detected[k]), float(toa_err[k]), float(rstd_err[k]), float(aoa_err[k]),
              bool(res.tags_valid[k]), k in used, k in excluded,
              float(np.asarray(res.peak_snr_db, float)[k]) if res.detected[k] else float("nan"),
              float(margin["hmac"][k]), float(margin["ds"][k]))
             for k in range(len(pos))]
    return (int(np.sum(res.detected)), len(used), ";".join(map(str, excluded))), links
