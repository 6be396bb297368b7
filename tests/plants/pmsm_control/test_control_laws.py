"""PI / CC / CEC control laws ([Thesis] §4.3), loss (eq. 4.16) and the failure definition."""
import math

import numpy as np
import pytest

from pfbench.plants.pmsm_control import (FailureCriterion, PIGains, cautious_control, cc_constants,
                             estimation_failed, pi_dq_control, pi_update, reference_speed,
                             tracking_loss)
from pfbench.models.pmsm import Pmsm

MODEL = Pmsm()
MP = MODEL.param_array()


def cp(u_max=10.0, gamma=0.1):
    return PIGains(u_max=u_max, gamma=gamma).array(MODEL)


def test_pi_update_hand_case():
    out, s = pi_update(3.0, 2.0, 0.5, 1.0)
    assert out == 2 * 3 + 0.5 * (1 + 3) and s == 4.0


def test_pi_dq_saturates_along_q_axis():
    u = np.empty(2)
    integ = np.zeros(3)
    pi_dq_control(0.0, 0.0, 0.0, 0.0, 1.0, integ, cp(), u)
    # iq_ref = 3*1 + 0.00375*1; u_q = 20.5 * iq_ref > 10 -> |U| = 10 along q (theta + pi/2)
    assert u == pytest.approx([0.0, 10.0], abs=1e-12)
    assert integ == pytest.approx([1.0, 0.0, 3.00375])
    integ = np.zeros(3)
    pi_dq_control(0.0, 0.0, 0.0, math.pi / 2, 1.0, integ, cp(), u)
    assert u == pytest.approx([-10.0, 0.0], abs=1e-12)


def test_pi_dq_unsaturated_and_compensation():
    u = np.empty(2)
    integ = np.zeros(3)
    pi_dq_control(0.0, 0.0, 0.0, 0.0, 0.01, integ, cp(), u)
    iq_ref = 3 * 0.01 + 0.00375 * 0.01
    assert u == pytest.approx([0.0, 20.5 * iq_ref], abs=1e-12)
    # on the set point with zero currents only the back-EMF compensation psi*omega remains
    integ = np.zeros(3)
    pi_dq_control(0.0, 0.0, 2.0, 0.0, 2.0, integ, cp(), u)
    assert u == pytest.approx([0.0, 2.0 * MODEL.flux], abs=1e-12)
    # d-axis current i_d = 1 at theta = 0 is pushed back by u_d = -(P_u + I_u) (+ L w i_q = 0)
    integ = np.zeros(3)
    pi_dq_control(1.0, 0.0, 0.0, 0.0, 0.0, integ, cp(u_max=100), u)
    assert u == pytest.approx([-20.5, 0.0], abs=1e-12)


def _bruteforce_cc(ia, ib, om, th, wn, w_ref, t, n, gamma):
    """Minimise gamma|u|^2 + sum_i w_i sum_k (omega_{t+k}(u) - ref_{t+k})^2 with the
    eq. 4.57 dynamics, by explicit matrix powers and least squares."""
    a, c, d, e = MP[0], MP[2], MP[3], MP[4]
    C = np.zeros((4, 2))
    C[0, 0] = C[1, 1] = c
    rows, rhs = [math.sqrt(gamma) * np.eye(2)], [np.zeros(2)]
    for i in range(len(om)):
        s, co = math.sin(th[i]), math.cos(th[i])
        A = np.array([[a, 0, 0, 0], [0, a, 0, 0], [-e * s, e * co, d, 0], [0, 0, 0, 1.0]])
        x = np.array([ia, ib, om[i], th[i]])
        for k in range(1, n + 1):
            Ak = np.linalg.matrix_power(A, k)
            Ak1 = np.linalg.matrix_power(A, k - 1)
            ref = w_ref[min(t + k, len(w_ref) - 1)]
            rows.append(math.sqrt(wn[i]) * (Ak1 @ C)[2:3, :])
            rhs.append(math.sqrt(wn[i]) * np.array([ref - (Ak @ x)[2]]))
    sol = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    return sol


def test_cautious_control_matches_bruteforce_minimiser():
    n = 30
    consts, S = cc_constants(MP, n)
    w_ref = reference_speed(400)
    om = np.array([1.0, -2.0, 0.5])
    th = np.array([0.3, 2.5, -1.0])
    wn = np.array([0.5, 0.2, 0.3])
    u = np.empty(2)
    cautious_control(0.4, -0.2, om, th, wn, w_ref, 100, consts, S, MP, cp(u_max=1e9, gamma=0.1), u)
    ref = _bruteforce_cc(0.4, -0.2, om, th, wn, w_ref, 100, n, 0.1)
    assert u == pytest.approx(ref, rel=1e-8, abs=1e-10)


def test_cautious_control_is_zero_under_uniform_theta():
    """Thesis §4.3.2: known zero currents, theta ~ U(-pi, pi) independent of omega -> u = 0."""
    consts, S = cc_constants(MP, 80)
    n = 60
    th = -math.pi + 2 * math.pi * (np.arange(n) + 0.5) / n
    u = np.empty(2)
    cautious_control(0.0, 0.0, np.zeros(n), th, np.full(n, 1 / n), np.full(200, 10.0), 0, consts,
                     S, MP, cp(), u)
    assert np.hypot(*u) < 1e-9


def test_cec_pushes_along_q_axis_and_is_capped():
    consts, S = cc_constants(MP, 80)
    u = np.empty(2)
    th = 0.7
    cautious_control(0.0, 0.0, np.array([0.0]), np.array([th]), np.ones(1), np.full(200, 10.0), 0,
                     consts, S, MP, cp(), u)
    assert np.hypot(*u) == pytest.approx(10.0)
    assert u / 10.0 == pytest.approx([-math.sin(th), math.cos(th)])


def test_cc_constants_closed_form():
    consts, S = cc_constants(MP, 80)
    a, d = MP[0], MP[3]
    k = np.arange(81)
    assert S == pytest.approx((d ** k - a ** k) / (d - a))
    # eq. 4.62-type closed form of sum_{k=1}^n S_{k-1} S_k for d = 1
    n = 80
    ref = sum((1 - a ** (j - 1)) * (1 - a ** j) for j in range(1, n + 1)) / (1 - a) ** 2
    assert consts[1] == pytest.approx(ref)


def test_tracking_loss_hand_case():
    u = np.array([[3.0, 4.0], [0.0, 0.0]])
    loss = tracking_loss(u, [1.0, 5.0], [0.0, 10.0], gamma=0.1)
    assert loss == pytest.approx([2.5 + 1.0, 25.0])
    ref = reference_speed(1600)
    assert ref[0] == 0 and ref[400] == pytest.approx(5.0) and ref[-1] == 10.0


def test_failure_definition():
    M = 1600
    ref = reference_speed(M)
    th = np.linspace(-3, 3, M)
    crit = FailureCriterion()
    assert not estimation_failed(th, th + 0.1, ref + 0.5, ref, crit)
    assert estimation_failed(th, th + math.pi, ref, ref, crit)             # pi away
    assert estimation_failed(th, th, -ref, ref, crit)                      # wrong direction
    assert not estimation_failed(th, th - 2 * math.pi + 0.2, ref, ref, crit)  # wrap handled
    assert estimation_failed(th, th + 1.7, ref, ref, crit) and not estimation_failed(
        th, th + 1.4, ref, ref, crit)
