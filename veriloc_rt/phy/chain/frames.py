"""The transmitter stage: the serving BSs' frame (PRS, encryption, tags) and its local replicas.

:class:`FrameSource` is configured once per chain (waveform, security, keys) and called per point
with the serving BSs and the frame counter. A serving set gets its transmitter
(:class:`~veriloc_rt.phy.transmitter.PRSTransmitter`) and tag verifier once (cached under its
:class:`ServingSet`); the last frame's signals are kept under their :class:`FrameKey` (the
scenarios of a point, and the adversary's relay, ask for the same frame in a row).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ...config.nr import NRConfig
from ...config.security import SecurityConfig
from ...propagation.cir import NO_TX
from ..channel import kept
from ..nr.ofdm import OFDM
from ..receiver.tag_verifier import TagVerifier
from ..security.keys import BSKeys, make_keys
from ..transmitter import PRSTransmitter
from .plan import REPLICAS

__all__ = ["DUMMY_ID", "FrameKey", "FrameSignals", "FrameSource", "ServingSet", "ServingSetup"]

#: identities given to empty serving slots (top of the u32 range the tags carry)
DUMMY_ID = 0xFFFF_FF00


@dataclass(frozen=True)
class ServingSet:
    """The serving BSs of a point, slot 0 the RSTD reference (``NO_TX``: an empty slot)."""

    bs_ids: tuple[int, ...]

    @classmethod
    def of(cls, bs_ids: Sequence[int]) -> "ServingSet":
        return cls(tuple(int(b) for b in bs_ids))

    @property
    def transmitted_ids(self) -> tuple[int, ...]:
        """The identities on air: an empty slot ``j`` transmits as ``DUMMY_ID + j``."""
        return tuple(b if b != NO_TX else DUMMY_ID + j for j, b in enumerate(self.bs_ids))


@dataclass(frozen=True)
class FrameKey:
    """What a frame's signals depend on: serving set, frame counter, replica mode."""

    serving: ServingSet
    frame: int
    replica: str
    every_tag: bool = False


@dataclass(frozen=True, eq=False)
class ServingSetup:
    """transmitter : PRSTransmitter of the serving set; verifier : TagVerifier or None (no tags)."""

    transmitter: PRSTransmitter
    verifier: TagVerifier | None


@dataclass(frozen=True, eq=False)
class FrameSignals:
    """One frame of the serving BSs, in the unit-RE normalisation.

    grids : [num_bs, num_slots, 14, num_subcarriers] complex128, what each BS transmits (its tags
        in the source's tag slots only, unless asked for every slot's:
        :attr:`FrameSource.tag_slots`)
    waveform : [num_bs, num_samples] complex128, the grids OFDM-modulated (time domain only,
        else None)
    replicas : tuple of [num_slots, 14, num_subcarriers] complex128, each BS's local PRS replica
        (read-only: the transmitter's kept arrays, one object for every frame of a standard PRS)
    occupied : [num_bs, num_slots, 14, num_subcarriers] bool, ``grids != 0`` (read-only; None:
        not known, compare the values)
    replica_occupied : tuple of [num_slots, 14, num_subcarriers] bool, ``replica != 0`` per BS
        (read-only; None: not known)
    """

    grids: np.ndarray
    waveform: np.ndarray | None
    replicas: tuple
    occupied: np.ndarray | None = None
    replica_occupied: tuple | None = None


#: serving sets whose transmitter and tag verifier a :class:`FrameSource` keeps
SETUPS_KEPT = 8


class FrameSource:
    """Transmitters, tag verifiers and frame signals of a chain.

    :param nr: waveform config; security: encryption and tags
    :param keys: by BS id, for encryption and tags (empty if neither is used); an empty slot's
        dummy identity gets keys drawn from its own seed
    :param time_domain: also OFDM-modulate the grids (the time-domain channel takes waveforms)
    :param tag_slots: indices (in the frame) of the slots whose tags a frame's grids carry unless
        asked for every slot's (None: every slot's): the slots whose tags the chain's receiver
        checks. Frequency domain only: there a tag RE's signal reaches that RE alone, so the
        empty tag REs of the other slots change nothing the receiver reads; in the time domain a
        Doppler shift spreads every RE over its neighbours
    """

    def __init__(self, nr: NRConfig, security: SecurityConfig, keys: Mapping[int, BSKeys],
                 time_domain: bool, tag_slots: Sequence[int] | None = None):
        self.nr, self.security = nr, security
        self.keys = dict(keys)
        self.time_domain = bool(time_domain)
        self.ofdm = OFDM(nr)
        self.slots = range(nr.slots_per_frame)
        self._setups: OrderedDict[ServingSet, ServingSetup] = OrderedDict()
        if tag_slots is not None and time_domain:
            raise ValueError("Argument `tag_slots` needs the frequency domain (time_domain False)")
        #: slot numbers whose tags the grids carry by default (None: every slot's)
        self.tag_slots = None if tag_slots is None else tuple(self.slots[int(i)] for i in tag_slots)
        #: the last frames by key (:func:`~veriloc_rt.phy.channel.kept`, emptied when a third
        #: comes): the chain's and a relay's, which asks for every tag
        self._last: dict[FrameKey, FrameSignals] = {}

    def setup(self, bs_ids: Sequence[int]) -> ServingSetup:
        """Transmitter and tag verifier of a serving set, kept for the :data:`SETUPS_KEPT` serving
        sets used last (each holds its PRS replicas, up to about 25 MB for 6 TRPs at 52 PRBs,
        and the default preset's 1200-point drive meets 33 sets, changing 214 times; a setup
        made again is the same, so what a chain computes does not depend on the bound)."""
        serving = ServingSet.of(bs_ids)
        if serving in self._setups:
            self._setups.move_to_end(serving)
        else:
            while len(self._setups) >= SETUPS_KEPT:
                self._setups.popitem(last=False)
            keys = dict(self.keys)
            ids_tx = serving.transmitted_ids
            for b in ids_tx:
                if b >= DUMMY_ID and self.keys:
                    keys[b] = make_keys(b, rng=np.random.default_rng(b))
            tx = PRSTransmitter(self.nr, self.security, ids_tx, keys or None)
            ver = (TagVerifier(self.nr, self.security, ids_tx, keys)
                   if self.security.tag_scheme != "none" else None)
            self._setups[serving] = ServingSetup(tx, ver)
        return self._setups[serving]

    def __call__(self, bs_ids: Sequence[int], frame: int, replica: str = "own",
                 every_tag: bool = False) -> FrameSignals:
        """Grids, waveforms and replicas of one frame (the last two kept: a chain's and a relay's).

        :param replica: one of :data:`~veriloc_rt.phy.chain.plan.REPLICAS`
        :param every_tag: the grids carry every slot's tags, whatever :attr:`tag_slots` (what a
            relay receives and amplifies: its gain depends on every RE)
        """
        if replica not in REPLICAS:
            raise ValueError(f"Argument `replica` must be one of {REPLICAS}, not {replica!r}")
        every = bool(every_tag) or self.tag_slots is None
        key = FrameKey(ServingSet.of(bs_ids), int(frame), replica, every)

        def make():
            tx = self.setup(bs_ids).transmitter
            tagged = None if every else self.tag_slots
            lean = (self._last.get(replace(key, every_tag=False))
                    if every and self.tag_slots is not None else None)
            if lean is not None:   # the chain's frame plus the other slots' tags
                grids = lean.grids.copy()
                tx.add_tags(grids, frame, self.slots, [s for s in self.slots if s not in self.tag_slots])
                return replace(lean, grids=grids, occupied=tx.occupied(self.slots)[0])
            grids = tx(frame, self.slots, tagged)
            wave = self.ofdm.modulate(grids, self.slots) if self.time_domain else None
            enc = None if replica == "own" else replica == "encrypted"
            reps = tuple(tx.replica(b, frame, self.slots, enc, copy=False) for b in range(self.nr.num_bs))
            return FrameSignals(grids, wave, reps, *tx.occupied(self.slots, tagged))

        return kept(self._last, key, make, max_entries=1)
