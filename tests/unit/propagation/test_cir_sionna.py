"""``CIR.to_sionna``: Sionna RT's ``Paths.cir`` layout and conventions (synthetic array), against
values written out by hand from the documented formula (sionna.rt.Paths.cir, Sionna RT 2.2:
``a_b,i(t) = a_i exp(-j 2 pi f tau_i) exp(j 2 pi f_D,i t)``; tau [num_rx, num_tx, num_paths];
delays normalised to each link's first path by default; invalid paths tau -1, a 0)."""

from __future__ import annotations

import numpy as np

from veriloc_rt.propagation.cir import CIR

FC = 3.5e9
#: the phases are of order 2 pi fc tau ~ 1e3 rad: double-precision exp of such arguments
#: agrees to ~1e-13; 1e-9 is ample
RTOL = 1e-9


def _cir() -> CIR:
    p, t, a, n = 2, 3, 2, 2
    delays = np.array([[[100e-9, 150e-9], [200e-9, 0.0], [0.0, 0.0]]] * p)
    valid = np.array([[[True, True], [True, False], [False, False]]] * p)
    gains = np.zeros((p, t, a, n), complex)
    gains[:, 0, :, 0] = [1e-4, 2e-4j]
    gains[:, 0, :, 1] = [3e-5, -1e-5]
    gains[:, 1, :, 0] = [5e-6, 5e-6]
    doppler = np.array([[[10.0, -20.0], [5.0, 0.0], [0.0, 0.0]]] * p)
    z = np.zeros((p, t, n))
    return CIR(delays=delays, gains=gains, aoa_az=z, aoa_zen=z, aod_az=z, aod_zen=z,
               doppler=doppler, interactions=np.zeros((p, t, n, 1), np.uint8), valid=valid,
               tx_index=np.array([[0, 1, -1]] * p), tx_pos=np.zeros((p, t, 3)),
               rx_pos=np.zeros((p, 3)), los=np.zeros((p, t), bool), carrier_frequency=FC)


def test_layout_and_values_by_hand():
    a, tau = _cir().to_sionna(1, num_time_steps=3, sampling_frequency=100.0)
    assert a.shape == (1, 2, 3, 1, 2, 3) and tau.shape == (1, 3, 2)
    # delays normalised to each link's first path; invalid -1
    np.testing.assert_allclose(tau[0], [[0.0, 50e-9], [0.0, -1.0], [-1.0, -1.0]], atol=1e-20)
    t = np.arange(3) / 100.0
    # link 0, antenna 1, path 1: gain -1e-5, normalised delay 50 ns, Doppler -20 Hz
    want = -1e-5 * np.exp(-2j * np.pi * FC * 50e-9) * np.exp(2j * np.pi * -20.0 * t)
    np.testing.assert_allclose(a[0, 1, 0, 0, 1], want, rtol=RTOL)
    # link 0, antenna 1, path 0: delay 0 after normalisation: no carrier phase
    np.testing.assert_allclose(a[0, 1, 0, 0, 0], 2e-4j * np.exp(2j * np.pi * 10.0 * t), rtol=RTOL)
    assert np.all(a[0, :, 1, 0, 1] == 0) and np.all(a[0, :, 2] == 0)   # invalid paths


def test_absolute_delays_keep_the_package_baseband_gains():
    cir = _cir()
    a, tau = cir.to_sionna(0, normalize_delays=False)
    np.testing.assert_array_equal(tau[0], np.where(cir.valid[0], cir.delays[0], -1.0))
    # one time step: the package's own baseband gains, axes [ant, tx, paths]
    np.testing.assert_allclose(a[0, :, :, 0, :, 0],
                               np.transpose(cir.baseband_gains()[0], (1, 0, 2)), rtol=RTOL)
