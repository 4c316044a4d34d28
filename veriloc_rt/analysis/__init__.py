"""The detection analysis of a run's rows: ROC and AUC of each detector (:mod:`.roc`), the fused
decisions (:mod:`.fusion`: k-of-n voting, Neyman-Pearson fusion) and the analysis of a whole
run over its scenarios (:mod:`.detection`). Above the detectors, below ``report/``, which writes
it (``roc.csv``, ``roc.png``, ``metrics.json``'s ``roc`` block).
"""
