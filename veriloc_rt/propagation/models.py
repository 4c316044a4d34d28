"""The propagation-model registry: ``propagation.model`` names a :class:`PropagationModel`.

A model computes every link of a run from its geometry: the serving BS -> UE, BS ->
adversary and adversary -> UE channel impulse responses
(:class:`~veriloc_rt.propagation.raytrace.Propagation`, each a
:class:`~veriloc_rt.propagation.cir.CIR`). The built-ins register here the way a plug-in does
(docs/extending.md, "A new propagation model"):

* ``raytrace``: Sionna RT on the scene (:func:`~veriloc_rt.propagation.raytrace.trace`);
* ``uma``, ``umi``: stochastic TR 38.901 UMa / UMi - Street Canyon
  (:func:`~veriloc_rt.propagation.stochastic.stochastic_propagation`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

from pathlib import Path
from typing import Callable

import numpy as np

from ..config import PropagationConfig
from ..registry import Registry
from .raytrace import Propagation, trace
from .stochastic import stochastic_propagation

__all__ = ["PROPAGATION_REGISTRY", "PropagationModel", "RayTracing", "StochasticUMa",
           "StochasticUMi"]


class PropagationModel(ABC):
    """Every link of a run from its geometry.

    Class attribute ``traces``: the model ray-traces the scene (its materials are checked
    before the run; the adversary's links are computed only where the run uses them).
    """

    #: set by the registry
    name: str = ""
    traces: bool = False

    @abstractmethod
    def __call__(self, geometry, cfg: PropagationConfig, seed: int, *,
                 progress: Callable[[int, int], None] | None = None,
                 cache_dir: str | Path | None = "default",
                 adversary_points: np.ndarray | None = None,
                 workers: int = 1) -> Propagation:
        """The links of ``geometry`` (a :class:`~veriloc_rt.world.geometry.Geometry`).

        :param cfg: the config's ``propagation`` section
        :param seed: the run's seed (every draw of a stochastic model derives from it)
        :param progress: called as ``progress(done, total)``
        :param cache_dir: a cache of computed links ("default": the config's; None: none)
        :param adversary_points: [num_points] bool, the points where the adversary's links
            are used (None: all); a model may compute them everywhere
        :param workers: processes the model may use
        """


#: propagation models by name (``propagation.model``)
PROPAGATION_REGISTRY: Registry[type[PropagationModel]] = Registry("propagation model",
                                                                  "propagation.model")


@PROPAGATION_REGISTRY.register("raytrace")
class RayTracing(PropagationModel):
    """Sionna RT on the scene (:func:`~veriloc_rt.propagation.raytrace.trace`)."""

    traces = True

    def __call__(self, geometry, cfg, seed, *, progress=None, cache_dir="default",
                 adversary_points=None, workers=1, ue_points=None):
        """As :meth:`PropagationModel.__call__`; ``ue_points`` ([num_points] bool, None: all)
        are the points whose BS -> UE links are traced (the others have no path)."""
        return trace(geometry, cfg, seed, progress=progress, cache_dir=cache_dir,
                     adversary_points=adversary_points, ue_points=ue_points, workers=workers)


@PROPAGATION_REGISTRY.register("uma")
class StochasticUMa(PropagationModel):
    """Stochastic TR 38.901 UMa (rooftop macro sites); every link drawn at every point (the
    draws are free, and stay the same whatever the attack window)."""

    def __call__(self, geometry, cfg, seed, *, progress=None, cache_dir="default",
                 adversary_points=None, workers=1):
        return stochastic_propagation(geometry, cfg, seed)


@PROPAGATION_REGISTRY.register("umi")
class StochasticUMi(StochasticUMa):
    """Stochastic TR 38.901 UMi - Street Canyon (street-level sites below the roofs)."""
