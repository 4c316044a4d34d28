"""Resource-grid layout of the serving BSs: PRS REs and tag REs in the comb's empty REs.

Each BS ``i`` maps its PRS with comb offset ``o_i`` (TS 38.211 7.4.1.7.3). With tags, BS ``i``'s
tag REs follow the same staggered comb pattern at offset ``(o_i + K_comb/2) mod K_comb``: this
reproduces the paper's dispersion figure for comb 6 (PRS offsets 0, 1, 2 and SIG offsets 3, 4, 5,
"three BSs' PRS plus three BSs' tags") and generalises it to the other comb sizes.

More TRPs than one slot holds share the frame by slot groups (``NRConfig.slot_plan``): group g
transmits in PRS slots g T_rep .. (g + 1) T_rep - 1 only (its resources' slot offset, TS 38.214
5.1.6.1), so REs collide only within a group.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import InputError
from ...config.nr import NRConfig
from .prs import SYMBOLS_PER_SLOT, check_comb, prs_subcarriers

#: occupancy code of an empty RE
EMPTY = 0


@dataclass(frozen=True)
class ReLayout:
    """Which REs of a slot each BS's PRS and tag occupy.

    :param num_subcarriers: grid width 12 N_PRB
    :param comb: K_comb
    :param num_symbols: L_PRS
    :param start_symbol: l_start
    :param prs_offsets: k_offset per BS
    :param tags: whether each BS also sends a tag at offset k_offset + K_comb/2
    :param groups: slot group of each BS (() : all in group 0, every slot)
    :param repetition: T_rep, the PRS slots of each group (0: every slot, one group)
    """

    num_subcarriers: int
    comb: int
    num_symbols: int
    start_symbol: int
    prs_offsets: tuple[int, ...]
    tags: bool
    groups: tuple[int, ...] = ()
    repetition: int = 0

    def __post_init__(self) -> None:
        check_comb(self.comb, self.num_symbols)
        if self.start_symbol + self.num_symbols > SYMBOLS_PER_SLOT:
            raise ValueError("Argument `start_symbol` leaves no room for the PRS symbols")
        self.occupancy()  # raises on collisions

    @classmethod
    def from_config(cls, nr: NRConfig, tags: bool, network_tags: bool | None = None) -> "ReLayout":
        """Layout of ``nr``; a collision between PRS and tag REs is an :class:`InputError`.

        :param network_tags: whether the network sends tags, which sets the slot groups
            (``NRConfig.slot_plan``; None: ``tags``): a transmitter without tags of its own
            (a spoofer's replicas) keeps the network's slots
        """
        groups, rep = nr.slot_plan(tags if network_tags is None else network_tags)
        one = max(groups) == 0
        try:
            return cls(nr.num_subcarriers, nr.comb, nr.num_symbols, nr.start_symbol,
                       tuple(nr.comb_offsets), tags, () if one else groups, 0 if one else rep)
        except ValueError as exc:
            raise InputError("nr.comb_offsets", str(exc)) from None

    @property
    def num_bs(self) -> int:
        return len(self.prs_offsets)

    def group(self, bs: int) -> int:
        return self.groups[bs] if self.groups else 0

    def transmits(self, bs: int, slot: int) -> bool:
        """BS ``bs`` sends its PRS (and tags) in PRS slot ``slot`` (counted from the frame's
        first PRS slot): its group's T_rep slots, or every slot with one group."""
        if not self.repetition:
            return True
        g = self.group(bs)
        return g * self.repetition <= int(slot) < (g + 1) * self.repetition

    def own_slot(self, bs: int, k: int) -> int:
        """The ``k``-th PRS slot BS ``bs`` transmits in (``k`` itself with one group)."""
        return self.group(bs) * self.repetition + int(k)

    @property
    def res_per_symbol(self) -> int:
        return self.num_subcarriers // self.comb

    @property
    def symbols(self) -> np.ndarray:
        """symbols : [num_symbols] int64, OFDM symbol indices l of the PRS in the slot."""
        return np.arange(self.start_symbol, self.start_symbol + self.num_symbols)

    def tag_offset(self, bs: int) -> int:
        return (self.prs_offsets[bs] + self.comb // 2) % self.comb

    def prs_subcarriers(self, bs: int) -> np.ndarray:
        """k : [num_symbols, res_per_symbol] int64, PRS subcarriers of BS ``bs`` per PRS symbol."""
        return prs_subcarriers(self.comb, self.num_symbols, self.prs_offsets[bs], self.num_subcarriers)

    def tag_subcarriers(self, bs: int) -> np.ndarray:
        """k : [num_symbols, res_per_symbol] int64, tag subcarriers of BS ``bs`` per PRS symbol."""
        if not self.tags:
            raise ValueError("this layout carries no tags")
        return prs_subcarriers(self.comb, self.num_symbols, self.tag_offset(bs), self.num_subcarriers)

    def prs_mask(self, bs: int) -> np.ndarray:
        """mask : [14, num_subcarriers] bool, True on the PRS REs of BS ``bs``."""
        return self._mask(self.prs_subcarriers(bs))

    def tag_mask(self, bs: int) -> np.ndarray:
        """mask : [14, num_subcarriers] bool, True on the tag REs of BS ``bs``."""
        return self._mask(self.tag_subcarriers(bs))

    def _mask(self, k: np.ndarray) -> np.ndarray:
        mask = np.zeros((SYMBOLS_PER_SLOT, self.num_subcarriers), dtype=bool)
        mask[self.symbols[:, None], k] = True
        return mask

    def occupancy(self) -> np.ndarray:
        """Who owns each RE: 0 empty, ``i + 1`` PRS of BS ``i``, ``-(i + 1)`` tag of BS ``i``
        (in the slots of group 0; every group's slots are checked).

        :return: owner : [14, num_subcarriers] int16
        :raises ValueError: if two signals share an RE
        """
        if self.groups and len(self.groups) != self.num_bs:
            raise ValueError(f"Argument `groups` must name one group per BS ({self.num_bs})")
        if self.groups and self.repetition < 1:
            raise ValueError("Argument `repetition` must be >= 1 with slot groups")
        return [self.group_occupancy(g) for g in sorted(set(self.groups or (0,)))][0]

    def group_occupancy(self, g: int) -> np.ndarray:
        """:meth:`occupancy` of the slots of group ``g`` (BSs of other groups absent there)."""
        members = [b for b in range(self.num_bs) if self.group(b) == g]
        if self.tags and 2 * len(members) > self.comb:
            raise ValueError(f"{len(members)} BSs with tags in one slot need comb >= "
                             f"{2 * len(members)}, not {self.comb}")
        owner = np.zeros((SYMBOLS_PER_SLOT, self.num_subcarriers), dtype=np.int16)
        for bs in members:
            claims = [(self.prs_mask(bs), bs + 1)]
            if self.tags:
                claims.append((self.tag_mask(bs), -(bs + 1)))
            for mask, code in claims:
                if np.any(owner[mask] != EMPTY):
                    raise ValueError(f"BS {bs} ({'tag' if code < 0 else 'PRS'}) collides with "
                                     f"another signal: offsets {self.prs_offsets}, comb {self.comb}")
                owner[mask] = code
        return owner
