"""Matplotlib (Agg) rendering of the landing envs: trajectory, lander and thrust vector."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["Renderer"]


def _arrow(ax, x: float, y: float, dx: float, dy: float, length_pt: float, label: str) -> None:
    """Arrow from data point (x, y) along the screen direction (dx, dy), ``length_pt`` long."""
    n = math.hypot(dx, dy) or 1.0
    ax.annotate("", xy=(x + 0.0, y + 0.0), xytext=(length_pt * dx / n, length_pt * dy / n),
                textcoords="offset points", annotation_clip=False,
                arrowprops=dict(arrowstyle="<|-", color="tab:red", lw=2.0))
    ax.plot([], [], color="tab:red", lw=2.0, label=label)


class Renderer:
    """Draws an episode history ``[(state_nd, control or None), ...]`` of a task.

    ``rgb_array`` returns an (H, W, 3) uint8 array from an off-screen Agg canvas; ``human``
    shows the same picture in a pyplot window (when the backend is interactive) and returns
    None.
    """

    def __init__(self, task, mode: str, size_px: tuple[int, int] = (640, 400)) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.task = task
        self.mode = mode
        dpi = 80
        self.fig = Figure(figsize=(size_px[0] / dpi, size_px[1] / dpi), dpi=dpi)
        self.canvas = FigureCanvasAgg(self.fig)
        self._window = None

    def draw(self, history: list):
        self.fig.clf()
        ys = np.array([h[0] for h in history]) if history else np.zeros((0, 1))
        if len(ys):
            u = next((h[1] for h in reversed(history) if h[1] is not None), None)
            if self.task.has_target:
                self._draw_pinpoint(ys, u)
            else:
                self._draw_planar(ys, u)
        self.canvas.draw()
        frame = np.asarray(self.canvas.buffer_rgba())[..., :3].copy()
        if self.mode == "human":
            self._show(frame)
            return None
        return frame

    def _draw_planar(self, ys: np.ndarray, u) -> None:
        tr = self.task.track(ys)
        ax = self.fig.add_subplot(1, 1, 1)
        x, h = tr["downrange_km"], tr["altitude_km"]
        ax.plot(x, h, "-", color="tab:blue", lw=1.5, label="trajectory")
        ax.axhline(0.0, color="0.4", lw=1.0)
        ax.plot(x[-1], h[-1], "o", color="k", ms=6, label="lander")
        if u is not None:
            # thrust direction in (downrange, up): cos φ opposes the motion (brakes); drawn at
            # its true angle on screen, length ∝ throttle
            phi, thr = float(u[0]), float(u[-1])
            _arrow(ax, x[-1], h[-1], -math.cos(phi), math.sin(phi), 45.0 * thr, "thrust")
        ax.set_xlabel("downrange (km)")
        ax.set_ylabel("altitude (km)")
        ax.set_title(f"{self.task.scenario.name}  t = {len(ys) - 1} steps, "
                     f"m = {ys[-1, -1] * self.task.mass_ref_kg:.1f} kg")
        ax.legend(loc="upper right", fontsize=8)
        self.fig.tight_layout()

    def _draw_pinpoint(self, ys: np.ndarray, u) -> None:
        tr = self.task.track(ys)
        # a task whose track has the speed (the touchdown task) also gets its speed profile
        n_panels = 3 if "speed_m_s" in tr else 2
        ax1 = self.fig.add_subplot(1, n_panels, 1)
        ax1.plot(tr["longitude_deg"], tr["latitude_deg"], "-", color="tab:blue")
        ax1.plot(tr["longitude_deg"][-1], tr["latitude_deg"][-1], "o", color="k")
        ax1.plot(*tr["target_deg"], "x", color="tab:red", ms=10, label="target")
        if u is not None:
            # horizontal thrust projection: azimuth β from the along-track heading
            lon, lat = tr["longitude_deg"], tr["latitude_deg"]
            if len(lon) > 1:
                head = math.atan2(lat[-1] - lat[-2], lon[-1] - lon[-2])
                ang = head + float(u[1])
                _arrow(ax1, lon[-1], lat[-1], math.cos(ang), math.sin(ang),
                       35.0 * math.cos(float(u[0])) * float(u[-1]), "thrust")
        ax1.set_xlabel("longitude (deg)")
        ax1.set_ylabel("latitude (deg)")
        ax1.set_title("ground track")
        ax1.legend(fontsize=8)
        ax2 = self.fig.add_subplot(1, n_panels, 2)
        x = tr["downrange_km"]
        ax2.plot(x, tr["altitude_km"], color="tab:blue")
        ax2.plot(x[-1], tr["altitude_km"][-1], "o", color="k")
        ax2.axhline(tr["target_altitude_km"], color="tab:red", lw=1.0, ls="--",
                    label=tr.get("target_altitude_label", "gate"))
        ax2.axvline(tr["target_downrange_km"], color="tab:red", lw=1.0, ls=":", label="target")
        if u is not None:  # thrust in the (along-track, up) plane: (cos α cos β, sin α)
            alpha, beta = float(u[0]), float(u[1])
            _arrow(ax2, x[-1], tr["altitude_km"][-1], math.cos(alpha) * math.cos(beta),
                   math.sin(alpha), 35.0 * float(u[-1]), "thrust")
        ax2.set_xlabel("downrange (km)")
        ax2.set_ylabel("altitude (km)")
        ax2.set_title("altitude")
        ax2.legend(fontsize=8)
        if n_panels == 3:
            ax3 = self.fig.add_subplot(1, n_panels, 3)
            t = np.arange(len(ys)) * float(tr["dt_s"])
            ax3.plot(t, tr["speed_m_s"], color="tab:blue")
            ax3.plot(t[-1], tr["speed_m_s"][-1], "o", color="k")
            ax3.set_xlabel("time (s)")
            ax3.set_ylabel("speed (m/s)")
            ax3.set_title("speed")
        self.fig.tight_layout()

    def _show(self, frame: np.ndarray) -> None:
        import matplotlib.pyplot as plt

        if self._window is None:
            fig, ax = plt.subplots()
            ax.axis("off")
            self._window = (fig, ax.imshow(frame))
        else:
            self._window[1].set_data(frame)
        self._window[0].canvas.draw_idle()
        plt.pause(0.001)

    def close(self) -> None:
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window[0])
            self._window = None
