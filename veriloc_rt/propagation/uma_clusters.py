"""TR 38.901 UMa / UMi-SC small-scale parameters: clusters and rays (7.5 steps 5-8, 10, 11).

One procedure for both scenarios; ``scenario`` ("uma", "umi") picks the table's constants
(cluster and ray counts, r_tau, zeta, c_DS, c_ASD, c_ASA, c_ZSA, C_phi, C_theta).

For a group of links that share a LoS state this draws cluster delays (step 5, with the LoS
delay scaling C_tau), cluster powers (step 6, per-cluster shadowing zeta, the -25 dB cluster
cut, the K-factor split), cluster and ray angles (step 7: wrapped-Gaussian azimuths with C_phi,
Laplacian zeniths with C_theta, random signs and jitters, LoS anchoring, Table 7.5-3 ray
offsets, ZOD offset and the 3/8 10^mu_lgZSD ZOD ray spread), random ray coupling (step 8) and
one random initial phase per ray (step 10). Step 11's sub-clustering splits the two strongest
clusters into three sub-clusters at delays +0, +1.28 c_DS, +2.56 c_DS with the Table 7.5-5 ray
groups (10, 6 and 4 rays of equal power, i.e. 10/20, 6/20, 4/20 of the cluster power).

Single vertical polarisation and isotropic elements: the step-11 polarisation matrix reduces to
its theta-theta entry exp(j Phi_tt), so the XPR of step 9 does not enter and is not drawn.
Every ray is returned as its own path (delay, power, four angles, phase); the array response
and the Doppler are applied by :mod:`veriloc_rt.propagation.uma`.
"""

from __future__ import annotations

import numpy as np

from . import tr38901


def _wrap_azimuth_deg(a: np.ndarray) -> np.ndarray:
    return (a + 180.0) % 360.0 - 180.0


def _wrap_zenith_deg(z: np.ndarray) -> np.ndarray:
    """Fold into [0, 180] deg (7.5 step 7: theta in [180, 360] -> 360 - theta)."""
    z = z % 360.0
    return np.where(z > 180.0, 360.0 - z, z)


def _cluster_angles(spread: np.ndarray, p_ang: np.ndarray, c_scale: np.ndarray,
                    anchor: np.ndarray, los: bool, laplacian: bool,
                    rng: np.random.Generator) -> np.ndarray:
    """Cluster centre angles of (7.5-9)..(7.5-16), deg.

    :param spread: [L] deg; p_ang: [L, N] powers used for angles; c_scale: [L] C_phi or C_theta
    :param anchor: [L] deg, LoS direction (plus the ZOD offset for NLoS ZOD)
    :returns: [L, N] float64, deg
    """
    rel = np.clip(p_ang / p_ang.max(axis=1, keepdims=True), 1e-12, 1.0)
    if laplacian:
        prime = -spread[:, None] * np.log(rel) / c_scale[:, None]
    else:
        prime = 2.0 * (spread[:, None] / 1.4) * np.sqrt(-np.log(rel)) / c_scale[:, None]
    sign = rng.choice(np.array([-1.0, 1.0]), size=prime.shape)
    jitter = rng.standard_normal(prime.shape) * (spread[:, None] / 7.0)
    ang = sign * prime + jitter
    if los:   # first cluster forced onto the LoS direction
        ang = ang - ang[:, :1]
    return ang + anchor[:, None]


def generate_rays(los: bool, fc_hz: float, ds: np.ndarray, asd: np.ndarray, asa: np.ndarray,
                  zsd: np.ndarray, zsa: np.ndarray, k_db: np.ndarray, mu_lg_zsd: np.ndarray,
                  zod_offset: np.ndarray, los_aoa_az: np.ndarray, los_aoa_zen: np.ndarray,
                  los_aod_az: np.ndarray, los_aod_zen: np.ndarray,
                  rng: np.random.Generator, scenario: str = "uma") -> dict[str, np.ndarray]:
    """Rays of a group of links in the same LoS state.

    ds : [L] float64, s; asd, asa, zsd, zsa : [L] float64, deg; k_db : [L] float64, dB (LoS only)
    mu_lg_zsd : [L] float64, lg(deg); zod_offset : [L] float64, deg
    los_aoa_az, los_aoa_zen, los_aod_az, los_aod_zen : [L] float64, rad, geometric directions
    (AoA: from the UE towards the BS; AoD: from the BS towards the UE)
    scenario : "uma" or "umi", the TR 38.901 table

    :returns: dict of [L, R] arrays, R = N M (+1 for the LoS ray, placed last):
        ``delay`` (s, excess over the direct path), ``power`` (linear, relative to the link's
        total, LoS ray K/(K+1)), ``aoa_az``, ``aoa_zen``, ``aod_az``, ``aod_zen`` (rad),
        ``phase`` (rad), ``valid`` (bool, False for clusters cut at -25 dB)
    """
    tab = tr38901.scenario_table(scenario)
    cp = tr38901.cluster_parameters(scenario, los, fc_hz)
    n, m = cp["num_clusters"], cp["rays_per_cluster"]
    nl = ds.size
    alpha = np.asarray(tab["ray_offsets"]["values"][:m])                # [M]

    # step 5: delays (unscaled ones feed the powers, 7.5-5 note)
    x = 1.0 - rng.random((nl, n))                                       # (0, 1]
    tau = -cp["r_tau"] * ds[:, None] * np.log(x)
    tau = np.sort(tau - tau.min(axis=1, keepdims=True), axis=1)
    k_lin = 10.0 ** (k_db / 10.0) if los else np.zeros(nl)
    if los:
        kd = k_db[:, None]
        c_tau = 0.7705 - 0.0433 * kd + 0.0002 * kd**2 + 0.000017 * kd**3
        tau_ch = tau / c_tau
    else:
        tau_ch = tau

    # step 6: powers
    z = rng.standard_normal((nl, n)) * cp["zeta_db"]
    pw = np.exp(-tau * (cp["r_tau"] - 1.0) / (cp["r_tau"] * ds[:, None])) * 10.0 ** (-z / 10.0)
    pw = pw / pw.sum(axis=1, keepdims=True)
    keep = pw >= pw.max(axis=1, keepdims=True) * 10.0 ** (-tab["cluster_drop_db"]["value"] / 10.0)
    p_ang = pw / (1.0 + k_lin[:, None])
    p_ang[:, 0] += k_lin / (1.0 + k_lin)

    # step 7: angles (deg)
    c_phi = np.full(nl, cp["c_phi_nlos"])
    c_theta = np.full(nl, cp["c_theta_nlos"])
    if los:
        kd = k_db
        c_phi = c_phi * (1.1035 - 0.028 * kd - 0.002 * kd**2 + 0.0001 * kd**3)
        c_theta = c_theta * (1.3086 + 0.0339 * kd - 0.0077 * kd**2 + 0.0002 * kd**3)
    deg = np.degrees
    zod_anchor = deg(los_aod_zen) + (0.0 if los else zod_offset)
    aoa = _cluster_angles(asa, p_ang, c_phi, deg(los_aoa_az), los, False, rng)
    aod = _cluster_angles(asd, p_ang, c_phi, deg(los_aod_az), los, False, rng)
    zoa = _cluster_angles(zsa, p_ang, c_theta, deg(los_aoa_zen), los, True, rng)
    zod = _cluster_angles(zsd, p_ang, c_theta, zod_anchor, los, True, rng)

    # ray angles: cluster centre + c_AS alpha_m; ZOD rays use (3/8) 10^mu_lgZSD (7.5-20)
    c_zsd = (3.0 / 8.0) * 10.0**mu_lg_zsd
    aoa_r = _wrap_azimuth_deg(aoa[..., None] + cp["c_asa_deg"] * alpha)
    aod_r = _wrap_azimuth_deg(aod[..., None] + cp["c_asd_deg"] * alpha)
    zoa_r = _wrap_zenith_deg(zoa[..., None] + cp["c_zsa_deg"] * alpha)
    zod_r = _wrap_zenith_deg(zod[..., None] + c_zsd[:, None, None] * alpha)

    # step 8: random coupling of AoD, ZoA, ZoD rays with the AoA rays inside each cluster
    aod_r = np.take_along_axis(aod_r, rng.permuted(np.broadcast_to(np.arange(m), aod_r.shape),
                                                   axis=-1), axis=-1)
    zoa_r = np.take_along_axis(zoa_r, rng.permuted(np.broadcast_to(np.arange(m), zoa_r.shape),
                                                   axis=-1), axis=-1)
    zod_r = np.take_along_axis(zod_r, rng.permuted(np.broadcast_to(np.arange(m), zod_r.shape),
                                                   axis=-1), axis=-1)

    # step 10: one random initial phase per ray (theta-theta term only)
    phase = rng.uniform(-np.pi, np.pi, size=(nl, n, m))

    # step 11: ray delays; the two strongest clusters split into three sub-clusters
    delay = np.broadcast_to(tau_ch[..., None], (nl, n, m)).copy()
    sub_off = np.zeros(m)
    for group, off in zip(tab["subclusters"]["rays_1based"],
                          tab["subclusters"]["delay_offsets_c_ds"]):
        sub_off[np.asarray(group) - 1] = off * cp["c_ds_s"]
    strongest = np.argsort(-pw, axis=1)[:, :2]                          # [L, 2]
    rows = np.arange(nl)[:, None]
    delay[rows, strongest] += sub_off
    ray_pw = np.broadcast_to((pw / (1.0 + k_lin[:, None]) / m)[..., None], (nl, n, m))
    valid = np.broadcast_to(keep[..., None], (nl, n, m))

    rad = np.radians
    out = {"delay": delay, "power": ray_pw, "aoa_az": rad(aoa_r), "aoa_zen": rad(zoa_r),
           "aod_az": rad(aod_r), "aod_zen": rad(zod_r), "phase": phase, "valid": valid}
    out = {k: v.reshape(nl, n * m) for k, v in out.items()}
    if los:   # the direct ray: zero excess delay, K/(K+1), geometric angles, zero phase
        extra = {"delay": np.zeros(nl), "power": k_lin / (1.0 + k_lin), "aoa_az": los_aoa_az,
                 "aoa_zen": los_aoa_zen, "aod_az": los_aod_az, "aod_zen": los_aod_zen,
                 "phase": np.zeros(nl), "valid": np.ones(nl, dtype=bool)}
        out = {k: np.concatenate([out[k], np.asarray(extra[k])[:, None]], axis=1) for k in out}
    return out
