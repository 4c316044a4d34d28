"""The CLI's presets: listed by `veriloc-rt config presets`, accepted by name as CONFIG, an
unknown name refused with the one-line contract before any work."""

from __future__ import annotations

from veriloc_rt.config.presets import DEFAULT_PRESET, PRESETS

from .test_bad_inputs import run_cli   # veriloc-rt ARGS in this process: (code, out, err)


def test_config_presets_lists_every_preset_and_marks_the_default():
    code, out, _ = run_cli("config", "presets")
    assert code == 0
    lines = out.splitlines()
    assert [ln.split(":")[0].split(" ")[0] for ln in lines] == sorted(PRESETS)
    assert [ln for ln in lines if "(default of run)" in ln] == \
        [ln for ln in lines if ln.startswith(DEFAULT_PRESET + " ")]


def test_a_preset_name_is_a_config(tmp_path):
    code, out, _ = run_cli("config", "show", "harsh-alley")
    assert code == 0 and '"num_trps": 3' in out
    code, out, _ = run_cli("config", "show", "3gpp-uma")
    assert code == 0 and '"num_trps": 9' in out and '"bs_max_power_dbm": 46.0' in out


def test_unknown_preset_is_refused_in_one_line_before_any_work(tmp_path):
    out = tmp_path / "out"
    code, _, err = run_cli("run", "3gpp-rma", "--out", out)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("error: 3gpp-rma: neither a config file nor a preset")
    assert not out.exists()
