"""Named scenario presets: configs shipped with the package, every parameter cited in
``docs/scenarios.md``.

A preset is a JSON config in ``veriloc_rt/data/presets/`` (``configs/<name>.json`` in the
repository is the same file, a test checks it); its relative paths (a sites CSV) resolve against
that folder, as a config file's do. ``veriloc-rt config presets`` lists them; a bare preset name
is accepted wherever a CONFIG path is (``veriloc-rt run 3gpp-umi-street``), and ``veriloc-rt
run`` without CONFIG runs :data:`DEFAULT_PRESET`. ``Config()`` itself stays the built-in
default (the ``harsh-alley`` canyon), the base every test and config file overrides.

Adding a preset: put ``<name>.json`` (and any file it names) into ``veriloc_rt/data/presets/``
and ``configs/``, add the name and a one-line summary to :data:`PRESETS`, and cite each of its
parameters in ``docs/scenarios.md`` (the section "Adding a preset" there).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from ..errors import InputError
from . import Config, load_config

#: preset name -> one-line summary (``veriloc-rt config presets`` prints them)
PRESETS = {
    "3gpp-umi-street": "TR 38.901 UMi - Street Canyon style: 23 street-level sites 10 m high "
                       "(below the 15 m roofs, about 205 m apart), 3 sectors of TR 38.901 "
                       "panels, 6 TRPs, 38 dBm (TS 38.104 medium range), 10 MHz / 15 kHz, "
                       "ray traced",
    "3gpp-uma": "TR 38.901 UMa style: rooftop macro sites 25 m high, ISD 500 m, 3 sectors of "
                "TR 38.901 panels (12 deg electrical downtilt), 9 TRPs, "
                "46 dBm (49 dBm per 20 MHz scaled to 10 MHz), 10 MHz / 15 kHz, ray traced",
    "harsh-alley": "the built-in canyon: 5 m streets between 15 m buildings, 3 TRPs 25 m high "
                   "at ISD 500 m, 24 dBm (TS 38.104 local area) against a 48 dBm adversary, "
                   "ray traced",
}

#: what ``veriloc-rt run`` runs without CONFIG
DEFAULT_PRESET = "3gpp-umi-street"


def preset_names() -> tuple[str, ...]:
    """The presets' names, sorted."""
    return tuple(sorted(PRESETS))


def preset_path(name: str) -> Path:
    """The packaged JSON file of preset ``name``.

    :raises InputError: naming ``name`` when no preset has it (one line, listing the presets)
    """
    if name not in PRESETS:
        raise InputError(name, f"no such preset (presets: {', '.join(preset_names())})")
    return Path(str(resources.files("veriloc_rt").joinpath("data", "presets", f"{name}.json")))


def load_preset(name: str) -> Config:
    """The validated config of preset ``name`` (its sites CSV resolved in the package)."""
    return load_config(preset_path(name))


def looks_like_preset(arg: str) -> bool:
    """``arg`` (a CONFIG argument) names a preset rather than a file: no existing file has that
    name, it does not end with ``.json`` and holds no path separator."""
    if arg.endswith(".json") or "/" in arg or "\\" in arg or "\0" in arg:
        return False
    try:
        return not Path(arg).exists()
    except (OSError, ValueError):   # a name no file can have (too long): the file reader's
        return False                # one-line error names it


def load_config_or_preset(arg: str | None, default: str | None = None) -> Config:
    """A CONFIG argument: a JSON file, a preset name, or None (preset ``default``, or the
    built-in ``Config()`` when that is None too).

    :raises InputError: a bad file (as :func:`load_config`) or an unknown preset name
    """
    if arg is None:
        return Config() if default is None else load_preset(default)
    if looks_like_preset(arg):
        if arg not in PRESETS:
            raise InputError(arg, "neither a config file nor a preset (presets: "
                             f"{', '.join(preset_names())})")
        return load_preset(arg)
    return load_config(arg)
