"""A radio link: log-distance path loss, the packet reception rate of FSK, bursts, a message budget.

Packet reception rate at distance d (the link-layer model of Zuniga and Krishnamachari,
"Analyzing the transitional region in low power wireless links", SECON 2004, section 3, for
non-coherent FSK):

    P_r(d) = P_t - PL(d_0) - 10 n log10(d / d_0)      received power, dBm (log-distance path loss,
                                                      Rappaport, Wireless Communications, eq. 4.68)
    γ(d) = 10^((P_r(d) - P_n) / 10)                   signal-to-noise ratio
    p_b = ½ exp(-γ / 2)                               bit error rate of non-coherent FSK
                                                      (Proakis, Digital Communications, eq. 5.4-47)
    PRR(d) = (1 - p_b)^(8 L)                          a frame of L bytes arrives whole

Bursts: each link (or, in the shared picture, each sender) is a Gilbert-Elliott chain
(:mod:`swarmscene.methods.disturbances.links`): in the bad state every message is lost, in the good one a message
is lost with probability 1 - PRR(d). Beyond ``range`` every message is lost.

Crazyflie-class parameters: P_t = 0 dBm (the Crazyflie 2.x nRF51822's default transmit power);
PL(d_0 = 1 m) = 20 log10(4 π d_0 / λ) = 40.05 dB at 2.4 GHz (Friis); n = 2 (free space, line of
sight; 2.7-3.5 indoors with walls); P_n = -93 dBm, the noise floor that puts the nRF24L01+'s
sensitivity at 2 Mbps (-82 dBm, its datasheet) at a bit error rate of 0.1 %; L = 32 bytes (the
Enhanced ShockBurst payload). With these, messages arrive whole up to about 100 m and are lost
beyond about 160 m.
"""

from __future__ import annotations

import numpy as np

FRIIS_1M_2G4 = 20.0 * np.log10(4.0 * np.pi * 1.0 / (299_792_458.0 / 2.4e9))
"""dB: free-space path loss at d_0 = 1 m at 2.4 GHz (40.05 dB)."""


def received_power(d, tx_power: float, loss_d0: float, exponent: float, d0: float = 1.0) -> np.ndarray:
    """P_r(d) dBm = P_t - PL(d_0) - 10 n log10(d / d_0) (d clipped at d_0: the near field is not modelled)."""
    d = np.maximum(np.asarray(d, dtype=float), d0)
    return tx_power - loss_d0 - 10.0 * exponent * np.log10(d / d0)


def reception_rate(d, tx_power: float, loss_d0: float, exponent: float, noise: float,
                   frame_bytes: int, d0: float = 1.0) -> np.ndarray:
    """PRR(d) = (1 - ½ exp(-γ / 2))^(8 L) (module docstring)."""
    snr = 10.0 ** ((received_power(d, tx_power, loss_d0, exponent, d0) - noise) / 10.0)
    return (1.0 - 0.5 * np.exp(-0.5 * snr)) ** (8 * frame_bytes)


def within_budget(dist: np.ndarray, arrived: np.ndarray, budget: int) -> np.ndarray:
    """Of the messages ``arrived`` (receiver i, sender j) (N, N), the ``budget`` nearest senders'
    per receiver (a radio takes at most ``budget`` messages per tick; the nearest first, as a
    receiver that ranks by signal strength keeps them)."""
    if budget >= dist.shape[1]:
        return arrived
    ranked = np.where(arrived, dist, np.inf)
    if budget <= 0:
        return np.zeros_like(arrived)
    kth = np.partition(ranked, budget - 1, axis=1)[:, budget - 1 : budget]
    keep = arrived & (ranked <= kth)
    # ties at the k-th distance: keep the lowest sender indices up to the budget
    over = keep.sum(axis=1) > budget
    if over.any():
        for i in np.flatnonzero(over):
            idx = np.flatnonzero(keep[i])
            keep[i, idx[np.argsort(ranked[i, idx], kind="stable")[budget:]]] = False
    return keep
