"""Attack sections of the config: the false base station, the meaconing relay and the jammer."""

from __future__ import annotations

from dataclasses import dataclass

from .fields import param, section

__all__ = ["FBS_MODES", "FBSConfig", "MeaconingConfig", "JammingConfig"]

FBS_MODES = ("target", "bias")


@dataclass(frozen=True)
class FBSConfig:
    """False-BS selective PRS spoofer."""

    target_offset_m: float = param(100.0, "distance of the target from the adversary's estimate "
                                   "of the UE position", lo=0.0, hi=100_000.0)
    target_bearing_deg: float = param(0.0, "direction of the offset (from +x, counter-clockwise)",
                                      lo=-360.0, hi=360.0)
    power_dbm: float = param(48.0, "transmit power of the spoofer", lo=-50.0, hi=90.0)
    tag_fill: str = param("random_qpsk", "what the spoofer puts in the tag REs: 'random_qpsk' "
                          "(forged tag attempt) or 'none' (empty)",
                          choices=("random_qpsk", "none"))
    mode: str = param("target", "'target': replica delays that move the fix to the target "
                      "(``target_offset_m`` from the UE estimate); 'bias': each spoofed BS's "
                      "replica arrives ``bias_s`` after that BS's own signal would reach the UE "
                      "estimate (a fixed timing bias on its RSTD, the paper's 'specific timing "
                      "delay': with a subset of BSs spoofed the biased hyperbolas meet off the UE, "
                      "or nowhere, a DoS)", choices=FBS_MODES)
    bias_s: float = param(2e-6, "mode 'bias': timing bias of every spoofed BS", lo=-100e-6,
                          hi=100e-6)
    link_gain: str = param("adversary", "the path gain the spoofer's signal reaches the UE with: "
                           "'adversary': its own adversary -> UE link (physical); 'spoofed_bs': "
                           "the link of the BS each replica imitates, i.e. the replica arrives "
                           "power_dbm minus that BS's path loss, as if it passed through the "
                           "imitated BS's channel (the paper's 'identical propagation ... but "
                           "transmitted at 48 dBm'); delays, Doppler and direction stay the "
                           "adversary's", choices=("adversary", "spoofed_bs"))
    spoofed_slots: tuple[int, ...] = param((), "serving-BS slots (0 = the RSTD reference) whose "
                                           "PRS the spoofer replicates; empty: all. A subset "
                                           "biases only those BSs' timing, the others keep the "
                                           "true geometry, so the fix lands off the target or "
                                           "not at all (the paper's 'selective' spoofing)")


@dataclass(frozen=True)
class MeaconingConfig:
    """Meaconing relay: transmit power, processing delay, gain cap."""

    power_dbm: float = param(48.0, "relay transmit power", lo=-50.0, hi=90.0)
    processing_delay_s: float = param(1e-6, "relay processing delay (common to all BSs)",
                                      lo=0.0, hi=1e-2)
    max_gain_db: float | None = param(None, "largest amplifier gain; null: unlimited",
                                      lo=0.0, hi=300.0)
    noise_figure_db: float | None = param(None, "noise figure of the relay's receiver; null: "
                                          "the UE's (channel.ue_noise_figure_db)", lo=0.0, hi=30.0)
    rx_antenna_gain_dbi: float = param(0.0, "gain of the relay's receive antenna towards the "
                                       "BSs (a directional or array antenna hears them above "
                                       "its own noise)", lo=-20.0, hi=40.0)


@dataclass(frozen=True)
class JammingConfig:
    """Wideband noise jammer."""

    power_dbm: float = param(48.0, "jammer transmit power", lo=-50.0, hi=90.0)

@dataclass(frozen=True)
class ThreatsConfig:
    """The adversary of each attack scenario (paper Sec. "Adversarial Threat Models")."""

    fbs: FBSConfig = section(FBSConfig, "selective PRS spoofing by a false BS")
    meaconing: MeaconingConfig = section(MeaconingConfig, "meaconing relay")
    jamming: JammingConfig = section(JammingConfig, "wideband jammer over the PRS band")

