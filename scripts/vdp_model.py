"""runs/vanderpol.toml's Van der Pol system, for the Python scripts that check hinf's figures on it
(scripts/vdp-rho-bound, scripts/vdp-linear-hinf): x = (p, w), p' = w, w' = mu (1 - p^2) w - p + v, y = p + c p^3 + n,
Q = I, x0 = (2, 0). Keep in step with the config."""
import numpy as np

MU, C3 = 1.0, 0.3
Q = np.eye(2)
B = np.array([[0.0], [1.0]])
X0 = np.array([2.0, 0.0])


def f(x):
    """The drift A(x)."""
    return np.array([x[1], MU * (1 - x[0] ** 2) * x[1] - x[0]])


def h(x):
    """The sensor C(x)."""
    return x[0] + C3 * x[0] ** 3


def jac_a(x):
    return np.array([[0.0, 1.0], [-2 * MU * x[0] * x[1] - 1.0, MU * (1 - x[0] ** 2)]])


def jac_c(x):
    return np.array([[1 + 3 * C3 * x[0] ** 2, 0.0]])


def riccati_rhs(P, A, C, rho):
    """P' of the finite-horizon H-infinity filter for hinf's game int x~'Q x~ <= rho int (|v|^2 + |n|^2)."""
    return A @ P + P @ A.T + B @ B.T - P @ (C.T @ C - Q / rho) @ P
