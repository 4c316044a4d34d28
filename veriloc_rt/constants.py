"""Physical constants, in SI units."""

#: Speed of light in vacuum [m/s]
SPEED_OF_LIGHT = 299_792_458.0

#: Boltzmann constant [J/K]
BOLTZMANN = 1.380_649e-23

#: Reference noise temperature [K] (kT = -174 dBm/Hz at 290 K)
REFERENCE_TEMPERATURE = 290.0
