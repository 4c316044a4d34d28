"""Config section of the NR waveform: numerology, bandwidth, PRS comb, per-BS offsets, sampling.

Per-BS tuples (``prs_ids``, ``comb_offsets``) are indexed by the BS's position in the serving set
(0 is the reference BS); their common length is the number of simultaneously transmitting BSs.
Tuples shorter than ``topology.num_trps`` are completed by :meth:`NRConfig.for_trps`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from .fields import param
from ..errors import InputError, bad_value

#: OFDM symbols per slot, normal cyclic prefix (TS 38.211 4.3.2)
SYMBOLS_PER_SLOT = 14
#: Allowed comb sizes K_comb and numbers of PRS symbols L_PRS (TS 38.211 7.4.1.7.3, 38.331)
COMB_SIZES = (2, 4, 6, 12)
NUM_SYMBOLS = (2, 4, 6, 12)

#: PRS resource repetition factors T_rep (TS 38.214 5.1.6.1, dl-PRS-ResourceRepetitionFactor)
REPETITION_FACTORS = (1, 2, 4, 6, 8, 16, 32)

#: Sub-carrier spacing at numerology 0 [Hz] (TS 38.211 4.2: 15 kHz * 2^mu)
SCS_MU0_HZ = 15e3
#: Largest supported sample rate [Hz]: the paper's 122.88 MHz is the reference
MAX_SAMPLE_RATE_HZ = 245.76e6


@dataclass(frozen=True)
class NRConfig:
    """5G NR DL PRS waveform (TS 38.211 7.4.1.7) and its OFDM sampling."""

    numerology: int = param(0, "subcarrier spacing 15 kHz * 2^mu", choices=(0, 1))
    num_prb: int = param(52, "bandwidth in PRBs (52 PRB = 10 MHz at mu = 0); PRS spans them all, "
                         "from point A", lo=24, hi=272)
    comb: int = param(6, "PRS comb size K_comb", choices=COMB_SIZES)
    num_symbols: int = param(12, "PRS symbols per slot L_PRS", choices=NUM_SYMBOLS)
    start_symbol: int = param(0, "first PRS symbol l_start in the slot", lo=0, hi=12)
    slots_per_frame: int = param(10, "slots per frame that carry PRS (slot 0 onwards); a frame "
                                 "has 10 * 2^mu slots", lo=1, hi=20)
    prs_ids: tuple[int, ...] = param((0, 1, 2), "dl-PRS-SequenceId (0..4095) per serving BS")
    comb_offsets: tuple[int, ...] = param((0, 1, 2), "PRS comb offset k_offset per serving BS; "
                                          "with tags, BS i's tag uses k_offset + K_comb/2")
    sample_rate_hz: float | None = param(None, "OFDM sample rate; null: the smallest power-of-two "
                                         "FFT rate holding the band (15.36 MHz for 52 PRB at mu=0); "
                                         "122.88 MHz is the reference", lo=0.0, lo_open=True,
                                         hi=MAX_SAMPLE_RATE_HZ)

    @property
    def num_bs(self) -> int:
        return len(self.comb_offsets)

    @property
    def num_subcarriers(self) -> int:
        return 12 * self.num_prb

    @property
    def subcarrier_spacing_hz(self) -> float:
        return SCS_MU0_HZ * 2**self.numerology

    @property
    def min_fft_size(self) -> int:
        """Smallest power-of-two FFT holding the band (at least 128)."""
        n = 128
        while n < self.num_subcarriers:
            n *= 2
        return n

    @property
    def fft_size(self) -> int:
        if self.sample_rate_hz is None:
            return self.min_fft_size
        return int(round(self.sample_rate_hz / self.subcarrier_spacing_hz))

    @property
    def resolved_sample_rate_hz(self) -> float:
        return self.fft_size * self.subcarrier_spacing_hz

    @property
    def prs_symbols(self) -> range:
        return range(self.start_symbol, self.start_symbol + self.num_symbols)

    def trps_per_slot(self, tags: bool) -> int:
        """TRPs whose PRS (and tags) one PRS slot holds on disjoint REs: one comb offset each,
        K_comb of them, or K_comb / 2 with tags (each TRP's tag takes the offset K_comb / 2 away)."""
        return self.comb // 2 if tags else self.comb

    def slot_plan(self, tags: bool) -> tuple[tuple[int, ...], int]:
        """Which PRS slots each TRP transmits in: TRPs are packed in order into groups of
        :meth:`trps_per_slot`; group g transmits in slots g T_rep .. (g + 1) T_rep - 1 of the
        frame's PRS slots. This is a PRS resource set whose resources carry
        dl-PRS-ResourceSlotOffset g T_rep, dl-PRS-ResourceRepetitionFactor T_rep and timeGap 1
        (TS 38.214 5.1.6.1). TS 38.211 7.4.1.7.4 puts a resource in slot n_s of frame n_f when
        (n_f N_slot + n_s - T_offset - T_offset,res) mod T_per = i T_gap for some i < T_rep (the
        38.211 text itself was not reachable here; the condition is OpenAirInterface's UE PRS
        slot check, docs/trps.md): with the frame as T_per, T_offset 0, T_offset,res g T_rep and
        T_gap 1 these are the slots above. T_rep is the largest of 38.214's repetition factors
        for which every group fits in nr.slots_per_frame. One group (the
        paper's three TRPs) transmits in every PRS slot, as before.

        :returns: (group of each TRP, T_rep: slots per group; nr.slots_per_frame for one group)
        :raises InputError: naming ``topology.num_trps`` when the groups outnumber the slots
        """
        per = self.trps_per_slot(tags)
        groups = tuple(i // per for i in range(self.num_bs))
        m = groups[-1] + 1
        if m == 1:
            return groups, self.slots_per_frame
        fits = [t for t in REPETITION_FACTORS if m * t <= self.slots_per_frame]
        if not fits:
            raise InputError("topology.num_trps", f"{self.num_bs} TRPs need {m} PRS slots of "
                             f"{per} TRPs each (comb {self.comb}{' with tags' if tags else ''}), "
                             f"but nr.slots_per_frame is {self.slots_per_frame}")
        return groups, fits[-1]

    def for_trps(self, n: int, tags: bool) -> "NRConfig":
        """This config with per-TRP tuples completed to ``n`` TRPs (the listed ones kept).

        dl-PRS-SequenceId (TS 38.211 7.4.1.7.2): each further TRP takes the next id above the
        largest listed (mod 4096), so the TRPs' scrambling sequences differ. Comb offset
        k_offset (TS 38.211 7.4.1.7.3): the first :meth:`trps_per_slot` TRPs (one slot's, as
        :meth:`slot_plan` groups them) take the lowest offsets that neither a listed TRP's PRS nor
        (with tags) its tag at k_offset + K_comb/2 uses, so their PRS REs are disjoint in
        frequency (TS 38.214 5.1.6.5's comb-multiplexed resources); the later slot groups repeat
        the first group's offsets (they transmit in other slots).
        """
        if n <= self.num_bs:
            return self
        ids = list(self.prs_ids)
        while len(ids) < n:
            nxt = (max(ids) + 1) % 4096
            while nxt in ids:
                nxt = (nxt + 1) % 4096
            ids.append(nxt)
        half, per = self.comb // 2, self.trps_per_slot(tags)
        first = list(self.comb_offsets[:per])
        used = set(first) | ({(o + half) % self.comb for o in first} if tags else set())
        for o in range(self.comb):
            if len(first) == min(n, per):
                break
            if o in used or (tags and (o + half) % self.comb in used):
                continue
            first.append(o)
            used |= {o, (o + half) % self.comb} if tags else {o}
        offsets = list(self.comb_offsets) if self.num_bs > per else first
        while len(offsets) < n:
            offsets.append(first[len(offsets) % per])
        return replace(self, prs_ids=tuple(ids), comb_offsets=tuple(offsets))

    def check_resources(self, tags: bool) -> None:
        """The TRPs of one slot group (:meth:`slot_plan`) use disjoint REs: distinct comb offsets
        and, with tags, no TRP's PRS or tag offset on another's.

        :raises InputError: naming ``nr.comb_offsets`` (or ``topology.num_trps``)
        """
        groups, _ = self.slot_plan(tags)
        half = self.comb // 2
        for g in set(groups):
            owner: dict[int, int] = {}
            for i in (i for i, gi in enumerate(groups) if gi == g):
                o = self.comb_offsets[i]
                for k in (o, (o + half) % self.comb) if tags else (o,):
                    if k in owner:
                        raise bad_value("nr.comb_offsets", list(self.comb_offsets),
                                        f"TRPs {owner[k]} and {i} share PRS slot group {g} and "
                                        f"subcarrier offset {k} (comb {self.comb}"
                                        f"{', tags at k_offset + K_comb/2' if tags else ''}): "
                                        "distinct offsets within each group of "
                                        f"{self.trps_per_slot(tags)} TRPs")
                    owner[k] = i

    def validate(self, path: str = "nr") -> None:
        """Cross-field checks; raise :class:`InputError` naming the field."""
        p = f"{path}." if path else ""
        if self.num_prb % 4:
            raise bad_value(f"{p}num_prb", self.num_prb, "a multiple of 4 (TS 38.211 PRS NumRB)")
        if self.num_symbols < self.comb or self.num_symbols % self.comb:
            raise bad_value(f"{p}num_symbols", self.num_symbols,
                            f"a multiple of comb {self.comb} (TS 38.211 7.4.1.7.3)")
        if self.start_symbol + self.num_symbols > SYMBOLS_PER_SLOT:
            raise bad_value(f"{p}start_symbol", self.start_symbol,
                            f"<= {SYMBOLS_PER_SLOT - self.num_symbols} for {self.num_symbols} symbols")
        if self.slots_per_frame > 10 * 2**self.numerology:
            raise bad_value(f"{p}slots_per_frame", self.slots_per_frame,
                            f"<= {10 * 2**self.numerology} at numerology {self.numerology}")
        if not self.comb_offsets:
            raise bad_value(f"{p}comb_offsets", self.comb_offsets, "at least one BS")
        if len(self.prs_ids) != self.num_bs:
            raise bad_value(f"{p}prs_ids", self.prs_ids, f"{self.num_bs} ids, one per comb offset")
        for i, n_id in enumerate(self.prs_ids):
            if not 0 <= n_id <= 4095:
                raise bad_value(f"{p}prs_ids[{i}]", n_id, "0..4095")
        for i, off in enumerate(self.comb_offsets):
            if not 0 <= off < self.comb:
                raise bad_value(f"{p}comb_offsets[{i}]", off, f"0..{self.comb - 1}")
        if self.sample_rate_hz is not None:
            ratio = self.sample_rate_hz / self.subcarrier_spacing_hz
            n = int(round(ratio))
            if abs(ratio - n) > 1e-9 * ratio or n & (n - 1) or n < self.min_fft_size:
                raise InputError(f"{p}sample_rate_hz",
                                 f"got {self.sample_rate_hz!r}, expected subcarrier spacing times a "
                                 f"power of two >= {self.min_fft_size} (e.g. "
                                 f"{self.min_fft_size * self.subcarrier_spacing_hz:.6g} ... 122.88e6)")

    def __post_init__(self) -> None:
        self.validate("")  # from_dict names the section
