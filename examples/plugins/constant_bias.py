"""Example plug-in threat: a constant-bias spoofer (docs/extending.md, "A new attack").

The adversary re-sends every serving TRP's standard PRS from its own position, each copy
timed so that it reaches the UE when that TRP's own signal does, except TRP slot ``SLOT``'s,
which it sends ``BIAS_S`` earlier: the UE's ToA of that TRP moves by ``c * BIAS_S`` (the copy
is the stronger and the earlier path), the others stay. Like the built-in ``fbs`` it knows the
UE's position (the strongest adversary). Register it by importing this module, then name it in
``run.scenarios``.
"""

from __future__ import annotations

import numpy as np

from veriloc_rt.attacks.threats import THREAT_REGISTRY, AttackPoint, Threat
from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.phy.channel import dbm_to_watt, re_amplitude

#: the biased TRP (serving slot) and its bias, s (negative: the copy arrives earlier)
SLOT = 1
BIAS_S = -0.5e-6
#: the spoofer's transmit power, split equally over its copies
POWER_DBM = 48.0


@THREAT_REGISTRY.register("constant_bias")
class ConstantBias(Threat):
    """Every serving TRP's PRS from the adversary, TRP ``SLOT``'s shifted by ``BIAS_S``."""

    label = "Constant bias"

    def grid(self, at: AttackPoint, rng: np.random.Generator) -> np.ndarray:
        s = self.signal
        bs_ids = tuple(int(b) for b in at.bs_ue.tx_index[at.point])
        frames = s.chain.frame_signals(bs_ids, at.frame)
        # the copies travel adversary -> UE; TRP k's own signal travels TRP k -> UE
        t_adv = np.linalg.norm(at.adversary_pos - at.ue_pos) / SPEED_OF_LIGHT
        t_bs = np.linalg.norm(at.bs_ue.tx_pos[at.point] - at.ue_pos, axis=1) / SPEED_OF_LIGHT
        power_w = dbm_to_watt(POWER_DBM) / len(bs_ids) * s.chain.bs_power_factor
        amp = float(re_amplitude(power_w, s.ofdm)) / s.unit
        out = np.zeros(s.shape, dtype=np.complex128)
        for k in range(len(bs_ids)):
            delay = t_bs[k] - t_adv + (BIAS_S if k == SLOT else 0.0)
            out += frames.grids[k] * s.delay_ramp(delay)[None, None, :]
        return amp * out
