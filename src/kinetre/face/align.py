"""Step 2 of Algorithm 2: weighted least-squares similarity alignment of the landmarks to the template.

E = Σ_i w_i ‖χ_i − (s R X_i + t)‖²  over scale s, rotation R ∈ SO(3), translation t, where X_i are the
template's vertices and χ_i the landmarks in a y-up camera frame (pixels: (x, −y, −z)). With a depth per
landmark (MediaPipe gives one) this is Umeyama's closed form. With 2D landmarks only (an annotation file),
the depths are unknowns too: E over the x, y rows alone is minimised by Gauss-Newton on the rotation,
log scale and image translation, from a closed-form scaled-orthographic start *(ours: the
paper aligns in 2D, which cancels roll only; the template's depth lets us cancel pitch and yaw as well)*.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Similarity:
    """x ↦ scale · rotation @ x + translation (template cm → camera pixels, y up)."""

    scale: float
    rotation: np.ndarray
    translation: np.ndarray

    def apply(self, points: np.ndarray) -> np.ndarray:
        return self.scale * points @ self.rotation.T + self.translation

    def inverse_apply(self, points: np.ndarray) -> np.ndarray:
        return (points - self.translation) @ self.rotation / self.scale


def umeyama(source: np.ndarray, target: np.ndarray, weights: np.ndarray) -> Similarity:
    """The similarity minimising Σ w_i ‖target_i − (s R source_i + t)‖² (Umeyama 1991, weighted)."""
    w = weights / weights.sum()
    mu_s, mu_t = w @ source, w @ target
    a, b = source - mu_s, target - mu_t
    cov = (b * w[:, None]).T @ a                      # Σ w b aᵀ
    u, sigma, vt = np.linalg.svd(cov)
    d = np.ones(3)
    d[2] = np.sign(np.linalg.det(u) * np.linalg.det(vt)) or 1.0
    rotation = (u * d) @ vt
    var = w @ (a * a).sum(axis=1)
    scale = float((sigma * d).sum() / var)
    return Similarity(scale, rotation, mu_t - scale * rotation @ mu_s)


def align(points: np.ndarray, template: np.ndarray, weights: np.ndarray, *, iterations: int = 20,
          tolerance: float = 1e-6) -> Similarity:
    """Pose of `template` (n, 3) that best explains `points` (n, 2) or (n, 3) in the y-up camera frame.

    `points` with a third column are aligned in 3D at once; 2D points run Gauss-Newton from the weighted
    affine camera fit made a scaled rotation (exact for noiseless orthographic views) until the step is
    below `tolerance`.
    """
    keep = weights > 0                                   # only the weighted landmarks enter E
    points, template, weights = points[keep], template[keep], weights[keep]
    if points.shape[1] == 3:
        return umeyama(template, points, weights)
    fit = _orthographic_start(points, template, weights)
    for _ in range(iterations):                   # Gauss-Newton on (rotation, log scale, t_xy)
        y = template @ fit.rotation.T                                  # R X
        r = (points - fit.scale * y[:, :2] - fit.translation[:2]).reshape(-1)
        jac = np.zeros((len(y), 2, 6))
        # d(R X)/dω for R ← exp([ω]×) R is −[R X]×; rows x, y of that, times s
        jac[:, 0, 1], jac[:, 0, 2] = fit.scale * y[:, 2], -fit.scale * y[:, 1]
        jac[:, 1, 0], jac[:, 1, 2] = -fit.scale * y[:, 2], fit.scale * y[:, 0]
        jac[:, :, 3] = fit.scale * y[:, :2]
        jac[:, 0, 4] = jac[:, 1, 5] = 1.0
        jac = jac.reshape(-1, 6)
        w2 = np.repeat(weights, 2)
        step = np.linalg.solve((jac * w2[:, None]).T @ jac + 1e-12 * np.eye(6), (jac * w2[:, None]).T @ r)
        rotation = _exp(step[:3]) @ fit.rotation
        fit = Similarity(fit.scale * float(np.exp(step[3])), rotation,
                         np.r_[fit.translation[:2] + step[4:], fit.translation[2]])
        if np.abs(step[:4]).max() < tolerance:
            break
    return fit


def _exp(omega: np.ndarray) -> np.ndarray:
    """Rodrigues: the rotation exp([ω]×)."""
    angle = float(np.linalg.norm(omega))
    if angle < 1e-12:
        return np.eye(3)
    k = omega / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx

def _orthographic_start(points: np.ndarray, template: np.ndarray, weights: np.ndarray) -> Similarity:
    """Scaled-orthographic pose from the weighted least-squares affine camera  χ ≈ M X + c  (M 2×3):
    M's nearest s·[r₁; r₂] with orthonormal rows (SVD), r₃ = r₁ × r₂."""
    w = weights / weights.sum()
    mu_x, mu_p = w @ template, w @ points
    a, b = template - mu_x, points - mu_p
    aw = a * w[:, None]
    m = np.linalg.solve(aw.T @ a, aw.T @ b).T                     # (2, 3)
    u, sigma, vt = np.linalg.svd(m, full_matrices=False)
    rows = u @ vt
    rotation = np.vstack([rows, np.cross(rows[0], rows[1])])
    scale = float(sigma.mean())
    t = np.r_[mu_p, 0.0] - scale * rotation @ mu_x
    return Similarity(scale, rotation, t)
