"""The TRP columns of a many-TRP run: written, read back for resume and for the plots."""

import numpy as np

from veriloc_rt.detectors.outcomes import DETECTORS, PointRow
from veriloc_rt.report.plots import read_results_csv
from veriloc_rt.report.results import ResultsWriter, read_rows


def _row(i, excluded):
    r = PointRow(index=i, time_s=float(i), attack=False, verdicts=dict.fromkeys(DETECTORS, True),
                 true_xy=np.zeros(2), est_xy=np.ones(2), error_m=1.0, outcome="success")
    r.trps = (9, 9 - len(excluded.split(";")) if excluded else 9, excluded)
    r.fix_cov = np.array([[2.0, 0.5], [0.5, 3.0]])
    r.auth = (7 / 9, np.array([1.5, np.nan]))
    r.links = [(k, k, 100.0 + k, -80.0, 12.0, True, 0.5, 0.1, 2.0, True, True, False)
               for k in range(9)]
    return r


def test_trp_columns_round_trip(tmp_path):
    path = tmp_path / "none_results.csv"
    with ResultsWriter(path, trps=True) as w:
        w.write(_row(0, "7;6"))
        w.write(_row(1, ""))
    back = read_rows(path)
    assert [r.trps for r in back] == [(9, 7, "7;6"), (9, 9, "")]
    np.testing.assert_array_equal(back[0].fix_cov, [[2.0, 0.5], [0.5, 3.0]])
    assert back[0].auth[0] == 7 / 9
    np.testing.assert_array_equal(back[0].auth[1], [1.5, np.nan])
    cols = read_results_csv(path)
    assert list(cols["bs_excluded"]) == ["7;6", ""] and list(cols["bs_used"]) == [7, 9]
    # a resume keeping the first row keeps its links only
    with ResultsWriter(path, keep=back[:1], trps=True):
        pass
    links = (tmp_path / "none_links.csv").read_text().splitlines()
    assert len(links) == 1 + 9 and all(ln.startswith("0,") for ln in links[1:])
