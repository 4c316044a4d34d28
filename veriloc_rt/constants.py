"""Physical constants in SI units, and the one conversion from a non-SI power unit."""

import numpy as np

#: Speed of light in vacuum [m/s]
SPEED_OF_LIGHT = 299_792_458.0

#: Boltzmann constant [J/K]
BOLTZMANN = 1.380_649e-23

#: Reference noise temperature [K] (kT = -174 dBm/Hz at 290 K)
REFERENCE_TEMPERATURE = 290.0


def dbm_to_watt(power_dbm):
    """Power in W of ``power_dbm`` (P_W = 10^((P_dBm - 30) / 10)): a float64 scalar or array."""
    return 10.0 ** ((np.asarray(power_dbm, dtype=float) - 30.0) / 10.0)
