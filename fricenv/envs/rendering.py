"""Drawing of the stick-slip environments: block on the belt, spring, recent velocity trace.

Imported only when an environment is made with a render mode, so training without rendering
never loads matplotlib. Frames are drawn on an Agg canvas (no display needed); ``"human"``
mode additionally shows them in a pyplot window when an interactive backend is available.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.image import AxesImage
from matplotlib.patches import FancyArrow, Rectangle

#: Velocity samples drawn per control interval (the trace is sampled on a copy of the state).
SAMPLES_PER_INTERVAL = 8
#: Length of the velocity trace shown, in time units (about three natural periods).
TRACE_WINDOW = 20.0

_SLIP_COLOR = "#3b6ea8"
_STICK_COLOR = "#c0392b"


class Trace:
    """Ring buffer of the recent velocity history of one plant."""

    def __init__(self, dt: float, window: float = TRACE_WINDOW):
        n_sub = SAMPLES_PER_INTERVAL
        self.buf_t = np.zeros(n_sub)  # filled by Steppers.sample_interval
        self.buf_v = np.zeros(n_sub)
        self.buf_s = np.zeros(n_sub, dtype=np.bool_)
        cap = n_sub * (int(math.ceil(window / dt)) + 2)
        self.t = np.zeros(cap)
        self.v = np.zeros(cap)
        self.s = np.zeros(cap, dtype=np.bool_)
        self.n = 0
        self.window = window

    def clear(self, t: float, v: float, stuck: bool) -> None:
        self.n = 0
        self._append(np.array([t]), np.array([v]), np.array([stuck]))

    def push(self) -> None:
        self._append(self.buf_t, self.buf_v, self.buf_s)

    def _append(self, t: np.ndarray, v: np.ndarray, s: np.ndarray) -> None:
        k = len(t)
        cap = len(self.t)
        if self.n + k > cap:
            keep = cap - k
            self.t[:keep] = self.t[self.n - keep : self.n]
            self.v[:keep] = self.v[self.n - keep : self.n]
            self.s[:keep] = self.s[self.n - keep : self.n]
            self.n = keep
        self.t[self.n : self.n + k] = t
        self.v[self.n : self.n + k] = v
        self.s[self.n : self.n + k] = s
        self.n += k

    def recent(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t, v, s = self.t[: self.n], self.v[: self.n], self.s[: self.n]
        if self.n:
            keep = t >= t[-1] - self.window
            t, v, s = t[keep], v[keep], s[keep]
        return t, v, s


class Painter:
    """One Agg figure, reused for every frame (and for every plant of a vector env)."""

    WALL = -5.0  # spring anchor; x = 0 is the relaxed spring
    BLOCK_W = 1.4
    BLOCK_H = 1.0

    def __init__(self, width: int = 640, height: int = 420):
        self.size = (width, height)
        dpi = 100
        self.fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
        self.canvas = FigureCanvasAgg(self.fig)
        self.ax = self.fig.add_axes((0.04, 0.52, 0.92, 0.40))
        self.ax_v = self.fig.add_axes((0.10, 0.10, 0.86, 0.34))
        ax = self.ax
        ax.set_axis_off()
        ax.set_ylim(-1.2, 2.2)
        ax.add_patch(Rectangle((-100, -0.6), 200, 0.6, color="#555555"))  # belt
        ax.add_patch(Rectangle((self.WALL - 0.4, -0.6), 0.4, 2.6, color="#999999"))  # wall
        (self.ticks,) = ax.plot([], [], "|", color="white", ms=9, mew=2)
        self.block = Rectangle((0, 0), self.BLOCK_W, self.BLOCK_H, color=_SLIP_COLOR)
        ax.add_patch(self.block)
        (self.spring,) = ax.plot([], [], color="black", lw=1.5)
        self.force: FancyArrow | None = None
        self.label = ax.text(0, 0, "", ha="center", va="center", color="white", fontsize=9)
        self.title = self.fig.text(0.5, 0.95, "", ha="center", va="center", fontsize=10)
        self.belt_label = ax.text(0, 0, "", ha="right", va="center", fontsize=8)

        av = self.ax_v
        (self.v_line,) = av.plot([], [], color=_SLIP_COLOR, lw=1.2)
        (self.v_stick,) = av.plot([], [], ".", color=_STICK_COLOR, ms=3)
        self.belt_line = av.axhline(1.0, color="gray", ls="--", lw=1, label="belt speed V")
        av.legend(loc="lower left", fontsize=7, frameon=False)
        av.set_xlabel("time")
        av.set_ylabel("velocity v")
        av.tick_params(labelsize=8)

    def __reduce__(self) -> tuple:
        # A figure's artists do not survive copy.deepcopy (they keep bound methods of the
        # original's artist lists), so a copied or unpickled painter draws on a new figure.
        return (Painter, self.size)

    def draw(self, snap: dict, trace: Trace) -> np.ndarray:
        x, V, t = snap["x"], snap["V"], snap["t"]
        ax = self.ax
        lo = min(self.WALL - 1.0, x - 2.0)
        hi = max(9.0, x + self.BLOCK_W + 2.0)
        ax.set_xlim(lo, hi)
        # Belt marks move with the belt: one per unit, or per power of ten keeping them under
        # 100 when the block is far out (a mark per unit at x = 1e12 would be a 7 TiB array).
        spacing = 10.0 ** max(0, math.ceil(math.log10((hi - lo) / 100.0)))
        shift = (V * t) % spacing
        marks = np.arange(math.floor(lo) - 1, hi + 1, spacing) + shift
        self.ticks.set_data(marks, np.full_like(marks, -0.3))
        left = x - self.BLOCK_W / 2
        self.block.set_xy((left, 0.0))
        self.block.set_color(_STICK_COLOR if snap["stuck"] else _SLIP_COLOR)
        self.label.set_position((x, self.BLOCK_H / 2))
        self.label.set_text("stick" if snap["stuck"] else "slip")
        # Spring: a zigzag from the wall to the block's left face.
        n = 16
        xs = np.linspace(self.WALL, left, 2 * n + 1)
        ys = np.full_like(xs, self.BLOCK_H / 2)
        ys[1:-1:2] += 0.25
        ys[2:-1:2] -= 0.25
        self.spring.set_data(xs, ys)
        if self.force is not None:
            self.force.remove()
            self.force = None
        g = snap["force"]
        if g != 0.0:  # the excitation force on the block, to scale
            self.force = FancyArrow(
                x,
                self.BLOCK_H + 0.5,
                0.5 * g,
                0.0,
                width=0.08,
                head_width=0.3,
                head_length=min(0.3, abs(0.5 * g)),
                color="#e67e22",
                length_includes_head=True,
            )
            ax.add_patch(self.force)
        self.belt_label.set_position((hi - 0.3, -0.95))
        self.belt_label.set_text(f"belt  V = {V:.2f}  \u2192")
        self.title.set_text(
            f"t = {t:7.2f}   u0 = {snap['u0']:.2f}   nu = {snap['nu']:.3f}   "
            f"force = {g:+.2f}   v - V = {snap['v'] - V:+.2f}"
        )
        tt, vv, ss = trace.recent()
        self.v_line.set_data(tt, vv)
        self.v_stick.set_data(tt[ss], vv[ss])
        self.belt_line.set_ydata([V, V])
        av = self.ax_v
        t1 = tt[-1] if len(tt) else t
        av.set_xlim(t1 - trace.window, t1 + 1e-9)
        vmin = min(float(vv.min()) if len(vv) else 0.0, V, -0.5) - 0.3
        vmax = max(float(vv.max()) if len(vv) else 0.0, V, 0.5) + 0.3
        av.set_ylim(vmin, vmax)
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba())[..., :3].copy()

    def close(self) -> None:
        self.fig.clear()


class Renderer:
    """Trace + painter + (for ``"human"``) a window, for the single environment."""

    def __init__(self, render_mode: str, fps: int, dt: float):
        self.render_mode = render_mode
        self.fps = fps
        self.trace = Trace(dt)
        self.buf_t, self.buf_v, self.buf_s = self.trace.buf_t, self.trace.buf_v, self.trace.buf_s
        self.painter: Painter | None = None
        self._window: tuple[Figure, AxesImage] | None = None
        self._warned = False  # the headless warning is given once per environment

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_window"] = None  # a copy opens a window of its own at its first frame
        return state

    def clear(self, t: float, v: float, stuck: bool) -> None:
        self.trace.clear(t, v, stuck)

    def push(self) -> None:
        self.trace.push()

    def render(self, snap: dict) -> np.ndarray | None:
        if self.painter is None:
            self.painter = Painter()
        frame = self.painter.draw(snap, self.trace)
        if self.render_mode == "rgb_array":
            return frame
        self._show(frame)
        return None

    def _show(self, frame: np.ndarray) -> None:
        """Show a frame in a pyplot window. Without an interactive backend (a headless
        machine, or Jupyter without ``%matplotlib``) nothing can be shown: say so once,
        rather than render to nowhere in silence."""
        import matplotlib
        from matplotlib.backends import BackendFilter, backend_registry

        backend = str(matplotlib.get_backend()).lower()
        if backend not in backend_registry.list_builtin(BackendFilter.INTERACTIVE):
            if not self._warned:
                self._warned = True
                warnings.warn(
                    f"render_mode='human' shows nothing: matplotlib's backend {backend!r} "
                    "is not interactive (a headless machine, or Jupyter without "
                    "'%matplotlib'); use render_mode='rgb_array' to get the frames",
                    UserWarning, stacklevel=4)
            return
        import matplotlib.pyplot as plt

        if self._window is None:
            fig = plt.figure(
                "fricenv StickSlip", figsize=(frame.shape[1] / 100, frame.shape[0] / 100)
            )
            ax = fig.add_axes((0, 0, 1, 1))
            ax.set_axis_off()
            self._window = (fig, ax.imshow(frame))
        else:
            self._window[1].set_data(frame)
        plt.pause(1.0 / self.fps)

    def close(self) -> None:
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window[0])
            self._window = None
        if self.painter is not None:
            self.painter.close()
            self.painter = None
