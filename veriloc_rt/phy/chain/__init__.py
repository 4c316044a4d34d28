"""The per-point positioning chain as stage blocks, in the order the signal flows.

* :mod:`.plan`: :class:`ChainPlan` (which receiver stages a call runs) and :class:`ChainResult`;
* :mod:`.frames`: the transmitter stage, :class:`FrameSource` -> :class:`FrameSignals`;
* :mod:`.downlink`: the channel stage, :class:`DownlinkChannel` -> :class:`DownlinkLinks`,
  :class:`Received` (the noise comes from a :mod:`veriloc_rt.phy.noise` source);
* :mod:`.receiver`: timing, fix, angles, tags and uplink stages;
* :mod:`.positioning`: :class:`PositioningChain`, the blocks composed, called per point.
"""

from .downlink import Adversary, DownlinkChannel, DownlinkLinks, Received
from .frames import FrameSignals, FrameSource
from .plan import FIX_ONLY, FULL, ChainPlan, ChainResult
from .positioning import STAGES, PositioningChain
from .receiver import AngleStage, Angles, FixStage, TagStage, Timing, TimingStage, UplinkStage

__all__ = ["Adversary", "AngleStage", "Angles", "ChainPlan", "ChainResult", "DownlinkChannel",
           "DownlinkLinks", "FIX_ONLY", "FULL", "FixStage", "FrameSignals", "FrameSource",
           "PositioningChain", "Received", "STAGES", "TagStage", "Timing", "TimingStage",
           "UplinkStage"]
