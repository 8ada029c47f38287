"""The vector environment's frames: each plant's recent motion, and the painter that draws it.

``PlantFrames`` is what ``StickSlipVectorEnv`` (``fricenv.envs.vector``) owns when it is
made with a render mode: a velocity trace per plant, which a step extends by sampling the
coming control interval before the kernel moves the plants, and the painter, made at the
first frame. It is handed the plants' arrays it reads, and reads nothing else. Matplotlib
is imported only when the frames are made (``fricenv.envs.rendering``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fricenv.envs import kernels as K
from fricenv.envs.steppers import Steppers
from fricenv.layout import S_MODE, S_PHI1, S_PHI2, S_T, S_V, S_X
from fricenv.params import P_U1, P_U2, P_V, P_XFK

if TYPE_CHECKING:
    from fricenv.envs.rendering import Painter


class PlantFrames:
    """The traces of ``n`` plants with control interval ``dt``, and their painter."""

    def __init__(self, n: int, dt: float):
        from fricenv.envs.rendering import Trace  # lazy: no matplotlib unless asked

        self.traces = [Trace(dt) for _ in range(n)]
        self._painter: Painter | None = None  # made at the first frame

    def clear(self, plants: np.ndarray | list[int], S: np.ndarray) -> None:
        """Start the traces of ``plants`` afresh from their states in ``S`` (n, N_STATE)."""
        for i in np.asarray(plants).tolist():
            self.traces[i].clear(S[i, S_T], S[i, S_V], S[i, S_MODE] == 0)

    def record(self, steppers: Steppers, plants: K.Plant, cfg: np.ndarray, a: np.ndarray,
               skip: np.ndarray | None) -> None:
        """Extend each plant's trace by the coming interval under its action ``a[i]``,
        sampled on copies with the step's kernels, except where ``skip`` is True (a plant
        the step restarts instead of stepping) or the action is not finite (the step
        refuses it). ``plants``: the batch's arrays, a row per plant."""
        for i, tr in enumerate(self.traces):
            if (skip is not None and skip[i]) or not K.actions_finite(a[i]):
                continue
            plant = K.Plant(*(rows[i] for rows in plants))
            status = steppers.sample_interval(plant, cfg, a[i],
                                              K.Trace(tr.buf_t, tr.buf_v, tr.buf_s))
            if status == 0:
                tr.push()

    def draw(self, snapshots: list[dict[str, float]]) -> tuple[np.ndarray, ...]:
        """One frame per plant, of its ``snapshots[i]`` and its trace."""
        if self._painter is None:
            from fricenv.envs.rendering import Painter

            self._painter = Painter()
        painter = self._painter
        return tuple(painter.draw(snap, tr) for snap, tr in zip(snapshots, self.traces,
                                                                  strict=True))

    def close(self) -> None:
        """Close the painter's figure (a later frame makes a new one)."""
        if self._painter is not None:
            self._painter.close()
            self._painter = None


def plant_snapshot(P: np.ndarray, S: np.ndarray, ctrl: np.ndarray,
                   x_limit: float) -> dict[str, float]:
    """What a frame draws of one plant (parameters ``P``, state ``S``, setting ``ctrl``)."""
    g = P[P_U1] * np.cos(S[S_PHI1]) + P[P_U2] * np.cos(S[S_PHI2])
    return {
        "t": float(S[S_T]),
        "x": float(S[S_X]),
        "v": float(S[S_V]),
        "V": float(P[P_V]),
        "stuck": bool(S[S_MODE] == 0.0),
        "u0": float(ctrl[0]),
        "nu": float(ctrl[1]),
        "force": float(g),
        "xfk": float(P[P_XFK]),
        "x_limit": x_limit,
    }
