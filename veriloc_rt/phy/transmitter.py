"""The legitimate BS transmitter: PRS (standard or AES-CTR encrypted) plus tags, per frame.

A :class:`PRSTransmitter` is configured once (waveform config, security config, the serving BS
ids and their keys) and called on a frame counter to give every BS's resource grid; its
:meth:`~PRSTransmitter.waveform` OFDM-modulates them. :func:`prs_replica` gives the receiver's
local PRS replica of one BS (standard, or encrypted with that BS's key).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..config.security import SecurityConfig
from .security.encryption import keystream_bits_many
from .security.keys import BSKeys
from .security.tag_modem import TagModem
from .security.tags import PRSParams, make_tag, tag_message
from ..config.nr import NRConfig
from .nr.grid import ReLayout
from .nr.ofdm import OFDM
from .nr.prs import SYMBOLS_PER_SLOT, prs_bits, qpsk

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class BSSetup:
    """One serving BS: its identity and the PRS configuration its tags bind."""

    bs_id: int
    prs: PRSParams


def serving_setup(nr: NRConfig, security: SecurityConfig, bs_ids: Sequence[int]) -> list[BSSetup]:
    """PRS set-up of each serving BS (position ``i`` takes ``nr.comb_offsets[i]`` etc.)."""
    if len(bs_ids) != nr.num_bs:
        raise ValueError(f"Argument `bs_ids` must name {nr.num_bs} BSs (one per comb offset), "
                         f"not {len(bs_ids)}")
    if len(security.encrypted) != nr.num_bs:
        raise ValueError(f"security.encrypted has {len(security.encrypted)} flags for {nr.num_bs} BSs")
    return [BSSetup(int(b), PRSParams(nr.prs_ids[i], nr.comb, nr.comb_offsets[i], nr.num_symbols,
                                      nr.start_symbol, nr.num_prb, nr.numerology,
                                      bool(security.encrypted[i])))
            for i, b in enumerate(bs_ids)]


def prs_replica(layout: ReLayout, bs: int, setup: BSSetup, frame: int, slots: Sequence[int],
                aes_key: bytes | None = None) -> np.ndarray:
    """PRS-only grid of BS position ``bs``: the local replica a receiver correlates with.

    :param aes_key: None for the standard PRS; the BS's key for its encrypted PRS
    :return: grid : [num_slots, 14, num_subcarriers] complex128, unit-energy PRS REs, 0 elsewhere
    """
    k = layout.prs_subcarriers(bs)
    n = layout.res_per_symbol
    grid = np.zeros((len(slots), SYMBOLS_PER_SLOT, layout.num_subcarriers), dtype=np.complex128)
    pairs = [(int(s), int(l)) for s in slots for l in layout.symbols]
    bits = np.array([prs_bits(setup.prs.n_id_seq, s, l, n) for s, l in pairs])       # [S L, 2 n]
    if aes_key is not None:   # b_PRSenc = b_PRS XOR p, every symbol's keystream in one AES call
        bits = bits ^ keystream_bits_many(aes_key, setup.bs_id, frame, pairs, 2 * n)
    r = qpsk(bits).reshape(len(slots), len(layout.symbols), n)
    grid[:, np.asarray(layout.symbols)[:, None], k] = r
    if layout.repetition:   # slot groups: nothing in the other groups' slots (ReLayout)
        grid[[not layout.transmits(bs, s) for s in slots]] = 0.0
    return grid


class PRSTransmitter:
    """Resource grids and waveforms of the serving BSs.

    :param nr: waveform config
    :param security: encryption flags, tag scheme and LDPC settings
    :param bs_ids: identity of the BS at each serving position
    :param keys: key set by BS id (BS side, with signing keys); needed for encryption and tags
    :param network_tags: whether the network sends tags (sets the TRPs' slot groups,
        :meth:`~veriloc_rt.phy.nr.grid.ReLayout.from_config`); None: this transmitter's own
    """

    def __init__(self, nr: NRConfig, security: SecurityConfig, bs_ids: Sequence[int],
                 keys: Mapping[int, BSKeys] | None = None, network_tags: bool | None = None):
        nr.validate()
        security.validate()
        self.nr, self.security = nr, security
        self.tags = security.tag_scheme != "none"
        self.layout = ReLayout.from_config(nr, self.tags, network_tags)
        self.setups = serving_setup(nr, security, bs_ids)
        needs_keys = self.tags or any(s.prs.encrypted for s in self.setups)
        if needs_keys:
            missing = [s.bs_id for s in self.setups if keys is None or s.bs_id not in keys]
            if missing:
                raise ValueError(f"no keys for BS {missing}")
        self.keys = dict(keys) if keys is not None else {}
        self.ofdm = OFDM(nr)
        self._standard: dict[tuple, np.ndarray] = {}
        self._encrypted: dict[tuple, np.ndarray] = {}
        self._occupied: dict[tuple, tuple] = {}
        self.modem = (TagModem(security.tag_scheme, self.layout.num_symbols * self.layout.res_per_symbol,
                               security.tag_fill, security.ldpc_iterations, security.ldpc_method)
                      if self.tags else None)

    @property
    def num_bs(self) -> int:
        return len(self.setups)

    def frame_slots(self, slots: Sequence[int] | None) -> list[int]:
        """The slot indices ``slots`` as a list (None: every PRS slot of a frame); raises
        ValueError for a slot outside the frame (10 * 2^mu slots, TS 38.211 4.3.2)."""
        if slots is None:
            return list(range(self.nr.slots_per_frame))
        out = [int(s) for s in slots]
        if any(not 0 <= s < 10 * 2**self.nr.numerology for s in out):
            raise ValueError(f"Argument `slots` must lie in 0..{10 * 2**self.nr.numerology - 1}")
        return out

    def replica(self, bs: int, frame: int, slots: Sequence[int] | None = None,
                encrypted: bool | None = None, *, copy: bool = True) -> np.ndarray:
        """Local PRS replica of serving BS ``bs`` (default: encrypted iff the BS encrypts).

        :param copy: False: the kept array itself, read-only (the standard PRS's one array for
            every frame, an encrypted one per frame), which a receiver may key its own derived
            values on
        :return: grid : [num_slots, 14, num_subcarriers] complex128
        """
        enc = self.setups[bs].prs.encrypted if encrypted is None else encrypted
        slots = self.frame_slots(slots)
        if enc:   # cached for the frame in hand (the grids and the receiver's replica share it)
            ck = (bs, tuple(slots), frame)
            if ck not in self._encrypted:
                if len(self._encrypted) >= 2 * self.num_bs:
                    self._encrypted.clear()
                key = self.keys[self.setups[bs].bs_id].aes_key
                self._encrypted[ck] = prs_replica(self.layout, bs, self.setups[bs], frame, slots, key)
                self._encrypted[ck].setflags(write=False)
            return self._encrypted[ck].copy() if copy else self._encrypted[ck]
        # the standard PRS is the same in every frame: cached per (BS position, slots)
        ck = (bs, tuple(slots))
        if ck not in self._standard:
            self._standard[ck] = prs_replica(self.layout, bs, self.setups[bs], frame, slots)
            self._standard[ck].setflags(write=False)
        return self._standard[ck].copy() if copy else self._standard[ck]

    def occupied(self, slots: Sequence[int] | None = None,
                 tag_slots: Sequence[int] | None = None) -> tuple[np.ndarray, tuple]:
        """The REs the frame's signals fill, the same in every frame (kept per slots and tag
        slots, read-only).

        A PRS RE carries a QPSK symbol, (+-1 +- j) / sqrt(2), never 0, standard or encrypted; a
        tag RE carries one where the modem places a codeword symbol (every tag RE with fill
        'repeat', the first E / 2 with 'single'). So these masks are ``grids != 0`` and
        ``replica != 0`` of every frame, without comparing a grid's values (a receiver uses them to
        find the REs it reads).

        :param tag_slots: as :meth:`__call__`'s
        :return: (grids [num_bs, num_slots, 14, num_subcarriers] bool, as :meth:`__call__`'s
            grids; replicas: per BS [num_slots, 14, num_subcarriers] bool, as :meth:`replica`'s)
        """
        slots = self.frame_slots(slots)
        tagged = self._tagged(slots, tag_slots)
        key = (tuple(slots), tuple(tagged))
        if key not in self._occupied:
            lay, n = self.layout, len(slots)
            reps = []
            grids = np.zeros((self.num_bs, n, SYMBOLS_PER_SLOT, lay.num_subcarriers), dtype=bool)
            for bs in range(self.num_bs):
                rep = np.broadcast_to(lay.prs_mask(bs), grids.shape[1:]).copy()
                on = np.array([lay.transmits(bs, s) for s in slots], dtype=bool)
                rep[~on] = False
                rep.flags.writeable = False
                reps.append(rep)
                grids[bs] = rep
                if self.tags:
                    used = np.zeros(lay.num_symbols * lay.res_per_symbol, dtype=bool)
                    used[:self.modem.copy_index.size] = True
                    k = lay.tag_subcarriers(bs)
                    mine = tagged[on[tagged]]
                    grids[bs][mine[:, None, None], lay.symbols[:, None], k] = used.reshape(k.shape)
            grids.flags.writeable = False
            self._occupied[key] = (grids, tuple(reps))
        return self._occupied[key]

    def tag_symbols(self, bs: int, frame: int, slot: int) -> np.ndarray:
        """QPSK tag symbols of BS ``bs`` for one slot, in tag-RE order (symbol, subcarrier).

        :return: x : [num_symbols * res_per_symbol] complex128
        """
        return self.tag_symbols_of_slots(bs, frame, [slot])[0]

    def tag_symbols_of_slots(self, bs: int, frame: int, slots: Sequence[int]) -> np.ndarray:
        """:meth:`tag_symbols` of several slots: [len(slots), num_symbols * res_per_symbol]."""
        if self.modem is None:
            raise ValueError("tag_scheme is 'none'")
        setup = self.setups[bs]
        scheme, key = self.security.tag_scheme, self.keys[setup.bs_id]
        return self.modem.modulate_many([make_tag(scheme, key, tag_message(scheme, setup.bs_id, frame, s,
                                                                           setup.prs))
                                         for s in slots])

    def _tagged(self, slots: list[int], tag_slots: Sequence[int] | None) -> np.ndarray:
        """Indices into ``slots`` of the slots that carry tags (every one for None)."""
        if tag_slots is None:
            return np.arange(len(slots))
        want = {int(s) for s in tag_slots}
        return np.array([i for i, s in enumerate(slots) if s in want], dtype=np.int64)

    def __call__(self, frame: int, slots: Sequence[int] | None = None,
                 tag_slots: Sequence[int] | None = None) -> np.ndarray:
        """Resource grids of frame ``frame`` (a 32-bit frame counter).

        :param tag_slots: slot numbers whose tags are written (None: every slot's); the tag REs
            of the other slots stay empty (a receiver that reads no tags there needs none: on a
            per-RE channel an RE's signal reaches no other RE)
        :return: grid : [num_bs, num_slots, 14, num_subcarriers] complex128
        """
        slots = self.frame_slots(slots)
        grids = np.stack([self.replica(bs, frame, slots, copy=False) for bs in range(self.num_bs)])
        self.add_tags(grids, frame, slots, tag_slots)
        log.debug("frame %d: %d BS x %d slots", frame, self.num_bs, len(slots))
        return grids

    def add_tags(self, grids: np.ndarray, frame: int, slots: Sequence[int] | None = None,
                 tag_slots: Sequence[int] | None = None) -> None:
        """Write the tags of frame ``frame`` into ``grids`` (as :meth:`__call__`'s, of ``slots``),
        in place: those of the slot numbers ``tag_slots`` (None: every slot's); nothing without
        a tag scheme."""
        slots = self.frame_slots(slots)
        tagged = self._tagged(slots, tag_slots)
        if not (self.tags and tagged.size):
            return
        sym = self.layout.symbols[:, None]
        for bs in range(self.num_bs):
            k = self.layout.tag_subcarriers(bs)
            mine = [i for i in tagged if self.layout.transmits(bs, slots[i])]
            if not mine:
                continue
            x = self.tag_symbols_of_slots(bs, frame, [slots[i] for i in mine])
            for i, xi in zip(mine, x):
                grids[bs, i, sym, k] = xi.reshape(k.shape)

    def waveform(self, frame: int, slots: Sequence[int] | None = None) -> np.ndarray:
        """Time-domain baseband of each BS.

        :return: x : [num_bs, num_samples] complex128 at ``nr.resolved_sample_rate_hz``
        """
        slots = self.frame_slots(slots)
        return self.ofdm.modulate(self(frame, slots), slots)
