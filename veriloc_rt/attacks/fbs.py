"""Selective PRS spoofing by a false BS (FBS): per-BS replica delays that place the UE at a target.

Paper Sec. "Selective PRS Spoofing". The adversary transmits, from its own position ``a``, a
standard-PRS replica of each targeted serving BS ``i`` delayed by ``d_i`` after the network's
frame start. All replicas reach the UE over the same path a -> UE, so the UE measures

    toa_i = d_i + |a - p_UE| / c        and        rstd_i = toa_i - toa_ref = d_i - d_ref,

i.e. the propagation a -> UE is common and cancels in every RSTD. Choosing
``d_i = |b_i - p_T| / c + const`` therefore gives the RSTDs of the target ``p_T`` exactly, for any
constant and without knowing the UE's exact position.

Assumptions (documented choices):

* **Timing**: the adversary knows the network's frame timing (it is synchronised to the BSs, e.g.
  by decoding their downlink and knowing its distance to them, modelled as ideal).
* **UE knowledge**: the adversary tracks the UE (the paper's adversary follows it 10 points
  behind) and knows the target BSs' PRS parameters and positions. It has an *estimate*
  ``p_UE_hat`` of the UE's position, not the exact one. The target is ``p_UE_hat + offset``, so an
  error in ``p_UE_hat`` moves the spoofed fix by that error; the RSTDs themselves are exact.
* **Alignment**: the "absolute" delays ``d_i = (|b_i - p_T| - |a - p_UE_hat|) / c`` would make each
  replica arrive when BS i's signal would arrive at the target (replicas overlap the legitimate
  correlation window; exact if ``p_UE_hat`` is exact). The adversary can only delay, so any
  negative delay shifts all delays by one common amount (``fbs_delays``), which changes no RSTD.
* **Mode 'bias'** (``FBSConfig.mode``): instead of a target, each spoofed BS's replica arrives
  a fixed ``bias_s`` after that BS's own signal would reach the UE estimate, the paper's "specific
  timing delay" that biases the RSTD. With every BS spoofed the bias is common and cancels; with a
  subset (``spoofed_slots``) the biased and the true hyperbolas meet off the UE, or not at all
  (multilateration's residual check: a DoS). A delay that would have to be negative (the
  adversary farther from the UE than a BS) moves all replicas later by the same amount.
* **Tags**: the adversary has no keys, so it cannot form valid tags: by default it fills the tag
  REs with random QPSK (its best attempt at a forged tag, which also spoils the legitimate tag's
  decoding under overshadowing); ``tag_fill='none'`` leaves them empty.
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass

import numpy as np

from ..config.attacks import FBSConfig
from ..constants import SPEED_OF_LIGHT, dbm_to_watt
from ..config.nr import NRConfig
from ..phy.nr.grid import ReLayout
from ..phy.nr.prs import qpsk
from ..phy.transmitter import PRSTransmitter
from ..config.security import SecurityConfig

__all__ = ["FBSConfig", "FBSPlan", "FalseBaseStation", "fbs_delays", "fbs_delays_absolute",
           "target_position", "spoofer_replicas", "biased_fix_outcomes"]

log = logging.getLogger(__name__)


def target_position(ue_estimate, offset_m: float, bearing_rad: float) -> np.ndarray:
    """p_T : [2 or 3] float64, m; the UE estimate moved ``offset_m`` horizontally along
    ``bearing_rad`` (height kept)."""
    p = np.array(ue_estimate, dtype=np.float64).reshape(-1)
    p[0] += offset_m * np.cos(bearing_rad)
    p[1] += offset_m * np.sin(bearing_rad)
    return p


def _check_positions(bs_pos, point, name: str) -> tuple[np.ndarray, np.ndarray]:
    b = np.asarray(bs_pos, dtype=np.float64)
    p = np.asarray(point, dtype=np.float64).reshape(-1)
    if b.ndim != 2 or b.shape[1] not in (2, 3) or b.shape[0] < 1:
        raise ValueError(f"Argument `bs_pos` must have shape [num_bs, 2 or 3], not {b.shape}")
    if p.size != b.shape[1]:
        raise ValueError(f"Argument `{name}` must have {b.shape[1]} coordinates like `bs_pos`, "
                         f"not {p.size}")
    if not (np.all(np.isfinite(b)) and np.all(np.isfinite(p))):
        raise ValueError(f"Arguments `bs_pos` and `{name}` must be finite")
    return b, p


def fbs_delays_absolute(bs_pos, target, adversary, ue_estimate) -> np.ndarray:
    """Unconstrained delays: replica i reaches ``ue_estimate`` when BS i's signal would reach
    ``target``.

    :param bs_pos: [num_bs, 2 or 3] float64, m; target, adversary, ue_estimate : [same] float64, m
    :return: d : [num_bs] float64, s, after the network frame start (may be negative)
    """
    b, t = _check_positions(bs_pos, target, "target")
    _, a = _check_positions(b, adversary, "adversary")
    _, u = _check_positions(b, ue_estimate, "ue_estimate")
    return (np.linalg.norm(b - t, axis=1) - np.linalg.norm(a - u)) / SPEED_OF_LIGHT


def fbs_delays(bs_pos, target, adversary=None, ue_estimate=None) -> np.ndarray:
    """Transmit delays (>= 0) whose RSTDs equal the target's.

    With ``adversary`` and ``ue_estimate``: :func:`fbs_delays_absolute` shifted by the smallest
    common amount that makes every delay >= 0 (unchanged when all are already >= 0). Without
    them: ``(|b_i - p_T| - min_j |b_j - p_T|) / c`` (earliest replica at delay 0).

    :return: d : [num_bs] float64, s, >= 0
    """
    b, t = _check_positions(bs_pos, target, "target")
    if (adversary is None) != (ue_estimate is None):
        raise ValueError("Arguments `adversary` and `ue_estimate` go together")
    if adversary is None:
        dist = np.linalg.norm(b - t, axis=1)
        return (dist - dist.min()) / SPEED_OF_LIGHT
    return _later_by_earliest(fbs_delays_absolute(b, t, adversary, ue_estimate))


def _later_by_earliest(d: np.ndarray) -> np.ndarray:
    """Delays moved later by one common amount so that none is negative (unchanged if none is):
    the spoofer can only delay, and a common shift changes no RSTD between its replicas."""
    return d - min(0.0, float(d.min()))


@dataclass(frozen=True, eq=False)
class FBSPlan:
    """What the spoofer transmits at one point.

    target : [2 or 3] float64, m; delays : [num_bs] float64, s (>= 0);
    replicas : list of (bs index, delay in s), the replicas to synthesise
    """

    target: np.ndarray
    delays: np.ndarray
    replicas: list


class FalseBaseStation:
    """Plans the spoofer's replicas per point.

    :param config: target offset, power, tag fill
    :param spoofed: serving-BS indices the spoofer replicates; None: all (partial sets reach the
        target RSTDs only between spoofed BSs, the others keep the true geometry)
    """

    def __init__(self, config: FBSConfig | None = None, spoofed=None):
        self.config = config if config is not None else FBSConfig()
        self.spoofed = None if spoofed is None else [int(i) for i in spoofed]

    @property
    def power_w(self) -> float:
        return float(dbm_to_watt(self.config.power_dbm))

    def __call__(self, bs_pos, adversary, ue_estimate) -> FBSPlan:
        """Plan for one point.

        :param bs_pos: [num_bs, 3] float64, m; adversary, ue_estimate : [3] float64, m
        """
        if self.config.mode == "bias":
            # the replicas arrive at the UE estimate bias_s after the BSs' own signals; the target
            # is then wherever the receiver's hyperbolas meet (NaN: not the spoofer's choice)
            t = np.full(np.asarray(ue_estimate).shape, np.nan)
            d = _later_by_earliest(fbs_delays_absolute(bs_pos, ue_estimate, adversary, ue_estimate)
                                   + self.config.bias_s)
        else:
            t = target_position(ue_estimate, self.config.target_offset_m,
                                np.radians(self.config.target_bearing_deg))
            d = fbs_delays(bs_pos, t, adversary, ue_estimate)
        idx = range(len(d)) if self.spoofed is None else self.spoofed
        return FBSPlan(t, d, [(int(i), float(d[i])) for i in idx])


@functools.lru_cache(maxsize=8)
def _spoofer_transmitter(nr: NRConfig, network_tags: bool) -> PRSTransmitter:
    """The spoofer's transmitter (standard PRS, no tags), made once per waveform: its standard
    PRS, the same in every frame, is then generated once and kept (its replicas are copies)."""
    security = SecurityConfig(encrypted=(False,) * nr.num_bs, tag_scheme="none")
    return PRSTransmitter(nr, security, list(range(nr.num_bs)), network_tags=network_tags)


def spoofer_replicas(nr: NRConfig, frame: int, replicas, rng: np.random.Generator, slots=None,
                     tag_fill: str = "random_qpsk", network_tags: bool = True) -> list:
    """Resource grids of the spoofer's replicas: standard (unencrypted) PRS, no valid tag.

    Built with :class:`~veriloc_rt.phy.transmitter.PRSTransmitter` (standard PRS, tag scheme
    'none'); the delay is carried along for the channel stage to apply.

    :param replicas: list of (bs index, delay in s), e.g. :attr:`FBSPlan.replicas`
    :param tag_fill: 'random_qpsk': unit-energy random QPSK on BS i's tag REs; 'none': empty
    :param network_tags: whether the network's layout has tag REs (where random QPSK goes)
    :return: list of (bs index, delay in s, grid : [num_slots, 14, num_subcarriers] complex128)
    """
    if tag_fill not in ("random_qpsk", "none"):
        raise ValueError(f"Argument `tag_fill` must be one of 'random_qpsk', 'none', not {tag_fill!r}")
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"Argument `rng` must be a numpy.random.Generator, not {type(rng).__name__}")
    tx = _spoofer_transmitter(nr, bool(network_tags))
    slots = tx.frame_slots(slots)
    layout = ReLayout.from_config(nr, True) if (tag_fill == "random_qpsk" and network_tags) else None
    out = []
    for bs, delay in replicas:
        if not 0 <= int(bs) < nr.num_bs:
            raise ValueError(f"replica BS index {bs} outside 0..{nr.num_bs - 1}")
        if not (np.isfinite(delay) and delay >= 0):
            raise ValueError(f"replica delay must be finite and >= 0, not {delay!r}")
        grid = tx.replica(int(bs), frame, slots, encrypted=False)
        if layout is not None:
            k = layout.tag_subcarriers(int(bs))
            sym = layout.symbols[:, None]
            bits = rng.integers(0, 2, size=(len(slots),) + k.shape + (2,), dtype=np.uint8)
            grid[:, sym, k] = qpsk(bits.reshape(bits.shape[:-2] + (-1,)))
            if layout.repetition:   # the imitated TRP's slots only (its slot group)
                grid[[not layout.transmits(int(bs), s) for s in slots]] = 0.0
        out.append((int(bs), float(delay), grid))
    log.debug("spoofer: %d replicas, frame %d", len(out), frame)
    return out


