"""Layer 4, physical layer: from BS to position fix, given the links' CIRs.

:mod:`.nr` (PRS, resource grid, OFDM, uplink SRS), :mod:`.security` (PRS encryption, tags,
keys, LDPC), :mod:`.transmitter` (the serving BSs' PRS grids), :mod:`.channel` (CIRs applied
to waveforms, powers, noise), :mod:`.noise` (noise sources), :mod:`.receiver` (sync, ToA/RSTD,
multilateration, AoA, tag checks, uplink) and :mod:`.chain` (the per-point chain as stage
blocks; :class:`~.chain.PositioningChain` runs them per point).
"""
