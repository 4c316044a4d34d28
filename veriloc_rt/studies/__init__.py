"""Layer 8, studies: questions asked of the chain beyond a run.

:mod:`.bench` (fidelity against time), :mod:`.compare` (ray tracing against UMa),
:mod:`.validate` (traced path loss against the published models), :mod:`.diagnostics`
(benign-chain quantities they share) and :mod:`.fbs_bias` (what the FBS timing bias does).
"""
