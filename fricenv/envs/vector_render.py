"""The vector environment's rendering: one frame per plant, with its recent motion.

``VectorRendering`` is a mixin of ``StickSlipVectorEnv`` (``fricenv.envs.vector``):
``render``, ``snapshot`` and the per-plant traces of the coming control interval that a
step records before the kernel moves the plants. Matplotlib is imported only when a frame
is drawn (``fricenv.envs.rendering``); kept apart from the stepping so that each module
holds one concern. The attributes it reads are the vector env's own, declared below for
the type checker.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium.vector import AutoresetMode

from fricenv.envs import kernels as K
from fricenv.envs.scenes import Scene
from fricenv.envs.steppers import Steppers
from fricenv.layout import S_MODE, S_PHI1, S_PHI2, S_T, S_V, S_X
from fricenv.params import P_U1, P_U2, P_V, P_XFK

if TYPE_CHECKING:
    from fricenv.envs.rendering import Painter, Trace


class VectorRendering:
    """Frames and traces of ``StickSlipVectorEnv`` (see the module docstring)."""

    # set by StickSlipVectorEnv.__init__ (and _bind_views: views of the kernels' arrays)
    scene: Scene
    num_envs: int
    render_mode: str | None
    _cfg: np.ndarray
    _autoreset_mode: AutoresetMode
    _steppers: Steppers
    _P: np.ndarray
    _S: np.ndarray
    _ctrl: np.ndarray
    _stats: np.ndarray
    _autoreset: np.ndarray
    _traces: list[Trace] | None  # each plant's recent motion (render_mode set), else None
    _painter: Painter | None  # made at the first render

    def render(self) -> tuple[np.ndarray, ...] | None:
        if self.render_mode is None:
            from gymnasium import logger

            logger.warn(
                "You are calling render method without specifying any render mode. "
                "You can specify the render_mode at initialization, e.g. "
                'gym.make_vec("fricenv/StickSlip-v0", render_mode="rgb_array") '
                'or StickSlipVectorEnv(render_mode="rgb_array")'
            )
            return None
        if self._painter is None:
            from fricenv.envs.rendering import Painter

            self._painter = Painter()
        painter, traces = self._painter, self._traces
        assert traces is not None  # made with the env whenever render_mode is set
        return tuple(painter.draw(self.snapshot(i), traces[i]) for i in range(self.num_envs))

    def close_extras(self, **kwargs: Any) -> None:
        if self._painter is not None:
            self._painter.close()
            self._painter = None

    def snapshot(self, i: int) -> dict[str, float]:
        P, S = self._P[i], self._S[i]
        g = P[P_U1] * np.cos(S[S_PHI1]) + P[P_U2] * np.cos(S[S_PHI2])
        return {
            "t": float(S[S_T]),
            "x": float(S[S_X]),
            "v": float(S[S_V]),
            "V": float(P[P_V]),
            "stuck": bool(S[S_MODE] == 0.0),
            "u0": float(self._ctrl[i, 0]),
            "nu": float(self._ctrl[i, 1]),
            "force": float(g),
            "xfk": float(P[P_XFK]),
            "x_limit": self.scene.x_limit,
        }

    def _record_traces(self, a: np.ndarray) -> None:
        traces = self._traces
        assert traces is not None  # called only when rendering
        for i, tr in enumerate(traces):
            if (self._autoreset_mode == AutoresetMode.NEXT_STEP and self._autoreset[i]) or (
                not K.actions_finite(a[i])
            ):
                continue
            status = self._steppers.sample_interval(
                self._P[i],
                self._S[i],
                self._ctrl[i],
                self._cfg,
                a[i],
                self._stats[i],
                tr.buf_t,
                tr.buf_v,
                tr.buf_s,
            )
            if status == 0:
                tr.push()
