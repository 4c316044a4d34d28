"""The scene-source registry: ``scene.source`` (and ``scene.osm``) name a :class:`SceneSource`.

A scene source builds the run's scene from the config: a procedural
:class:`~veriloc_rt.world.scene.canyon.UrbanCanyon` or a checked
:class:`~veriloc_rt.world.scene.external.MeshScene`;
:func:`~veriloc_rt.world.geometry.build_geometry` then crops it to the BSs and the trajectory
and writes the XML + PLY files the tracer reads. The built-ins register here the way a plug-in
does (docs/extending.md, "A new scene source"):

* ``canyon``: the procedural Manhattan grid (``scene.source = "canyon"``);
* ``xml``: a Mitsuba XML scene file (``scene.source`` a path ending in ``.xml``);
* ``sionna``: a scene bundled with Sionna RT (``scene.source = "sionna:<name>"``);
* ``osm``: a local OpenStreetMap extract imported into the run's ``scene/osm/`` folder
  (``scene.osm`` set; ``scene.source`` stays ``"canyon"``).

A plug-in is named as ``scene.source = "<name>"`` or ``"<name>:<argument>"``
(:attr:`~veriloc_rt.config.SceneConfig.source_name`,
:attr:`~veriloc_rt.config.SceneConfig.source_arg`).
The config sits below this package, so it checks only the form of a name;
:func:`veriloc_rt.sim.plugins.check_plugin_names` looks it up before anything is computed.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import logging
from pathlib import Path

from ..config import Config
from ..errors import InputError
from ..registry import Registry
from ..rng import stream
from .scene.canyon import UrbanCanyon, urban_canyon
from .scene.external import MeshScene
from .scene.osm import OSM_MATERIALS
from .scene.osm_write import osm_scene

__all__ = ["SCENE_SOURCE_REGISTRY", "SceneSource", "Canyon", "XmlScene", "BundledScene",
           "OsmExtract", "osm_scene_xml", "scene_source"]

log = logging.getLogger(__name__)


def osm_scene_xml(scfg, scene_dir: str | Path) -> Path:
    """The scene imported from ``scene.osm`` into ``scene_dir`` (reused when already there)."""
    xml, city = osm_scene(scfg.osm, scene_dir, bbox_deg=scfg.osm_bbox_deg or None,
                          radius_m=scfg.osm_radius_m, storey_m=scfg.osm_storey_m,
                          default_height_m=scfg.osm_default_height_m,
                          ground_material=scfg.ground_material,
                          thickness_m=scfg.material_thickness_m)
    if city is not None:
        log.info("OSM: %d buildings, %d street nodes from %s", city.num_buildings,
                 len(city.street_nodes), scfg.osm)
    return xml


#: the scene-source registry (``scene.source``)
SCENE_SOURCE_REGISTRY: Registry[type["SceneSource"]] = Registry("scene source", "scene.source")


class SceneSource(ABC):
    """A run's scene from its config.

    Subclasses implement :meth:`load`; :meth:`materials` (the ITU materials Sionna RT will trace,
    checked against the carrier frequency before a ray-traced run) defaults to the config's
    ``scene.building_material`` and ``scene.ground_material``.
    """

    #: set by the registry
    name: str = ""

    @abstractmethod
    def load(self, cfg: Config, scene_dir: Path) -> UrbanCanyon | MeshScene:
        """The whole scene (before the crop).

        :param scene_dir: the run's scene folder, where a source may write files it builds
        :raises InputError: one line naming the config field at fault
        """

    def materials(self, cfg: Config) -> list[tuple[str, str, str]]:
        """``(config field, ITU material, message)`` of each material the scene uses; the
        message holds ``{problem}``, where the check puts what is wrong."""
        msg = "{problem} (propagation.carrier_frequency_hz)"
        return [(f"scene.{n}", getattr(cfg.scene, n), msg)
                for n in ("building_material", "ground_material")]


def scene_source(cfg: Config) -> SceneSource:
    """The registered source ``cfg.scene`` names, instantiated.

    :raises InputError: ``scene.source``: an unknown source, with the registered names
    """
    return SCENE_SOURCE_REGISTRY.get(cfg.scene.source_name, "scene.source")()


@SCENE_SOURCE_REGISTRY.register("canyon")
class Canyon(SceneSource):
    """The procedural Manhattan grid of ``scene`` (heights seeded from the run's seed)."""

    def load(self, cfg: Config, scene_dir: Path) -> UrbanCanyon:
        return urban_canyon(cfg.scene, stream(cfg.seed, "scene-heights"))


class _MeshFile(SceneSource):
    """A Mitsuba XML scene file: its materials are the file's ITU materials."""

    def load(self, cfg: Config, scene_dir: Path) -> MeshScene:
        return MeshScene.from_xml(cfg.scene.xml_path)

    def materials(self, cfg: Config) -> list[tuple[str, str, str]]:
        from .scene.export import scene_itu_materials
        msg = cfg.scene.source.replace("{", "(").replace("}", ")") + ": {problem}"
        return [("scene.source", m, msg) for m in scene_itu_materials(cfg.scene.xml_path)]


@SCENE_SOURCE_REGISTRY.register("xml")
class XmlScene(_MeshFile):
    """A Mitsuba XML scene (metres, z up, flat ground at z = 0 holding the origin)."""


@SCENE_SOURCE_REGISTRY.register("sionna")
class BundledScene(_MeshFile):
    """A scene bundled with Sionna RT, ``sionna:<name>``."""


@SCENE_SOURCE_REGISTRY.register("osm")
class OsmExtract(SceneSource):
    """A local OpenStreetMap extract, imported into ``<scene_dir>/osm`` (reused when there)."""

    def load(self, cfg: Config, scene_dir: Path) -> MeshScene:
        if not cfg.scene.osm:
            raise InputError("scene.source", "'osm' is chosen by setting scene.osm to the "
                             "extract (scene.source stays 'canyon')")
        return MeshScene.from_xml(osm_scene_xml(cfg.scene, Path(scene_dir) / "osm"), "scene.osm")

    def materials(self, cfg: Config) -> list[tuple[str, str, str]]:
        msg = ("{problem} (OSM buildings map to " + ", ".join(OSM_MATERIALS)
               + "; propagation.carrier_frequency_hz)")
        return [("scene.osm", m, msg) for m in OSM_MATERIALS] + [
            ("scene.ground_material", cfg.scene.ground_material,
             "{problem} (propagation.carrier_frequency_hz)")]
