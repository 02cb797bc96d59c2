"""Matplotlib (Agg) rendering of the landing envs: trajectory, lander and thrust vector."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["Renderer"]


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
            # thrust direction in (downrange, up): cos φ opposes the motion (brakes)
            phi, thr = float(u[0]), float(u[-1])
            span = max(float(np.ptp(x)), float(np.ptp(h)), 1.0)
            L = 0.08 * span * thr
            ax.annotate("", xy=(x[-1] - L * math.cos(phi), h[-1] + L * math.sin(phi)),
                        xytext=(x[-1], h[-1]), arrowprops=dict(color="tab:red", width=1.5,
                                                               headwidth=6))
        ax.set_xlabel("downrange (km)")
        ax.set_ylabel("altitude (km)")
        ax.set_title(f"{self.task.scenario.name}  t = {len(ys) - 1} steps, "
                     f"m = {ys[-1, -1] * self.task.mass_ref_kg:.1f} kg")
        ax.legend(loc="upper right", fontsize=8)
        self.fig.tight_layout()

    def _draw_pinpoint(self, ys: np.ndarray, u) -> None:
        tr = self.task.track(ys)
        ax1 = self.fig.add_subplot(1, 2, 1)
        ax1.plot(tr["longitude_deg"], tr["latitude_deg"], "-", color="tab:blue")
        ax1.plot(tr["longitude_deg"][-1], tr["latitude_deg"][-1], "o", color="k")
        ax1.plot(*tr["target_deg"], "x", color="tab:red", ms=10, label="target")
        if u is not None:
            # horizontal thrust projection: azimuth β from the along-track heading
            lon, lat = tr["longitude_deg"], tr["latitude_deg"]
            if len(lon) > 1:
                head = math.atan2(lat[-1] - lat[-2], lon[-1] - lon[-2])
                ang = head + float(u[1])
                L = 0.05 * max(float(np.ptp(lon)), float(np.ptp(lat)), 0.1)
                ax1.annotate("", xy=(lon[-1] + L * math.cos(ang), lat[-1] + L * math.sin(ang)),
                             xytext=(lon[-1], lat[-1]),
                             arrowprops=dict(color="tab:red", width=1.2, headwidth=5))
        ax1.set_xlabel("longitude (deg)")
        ax1.set_ylabel("latitude (deg)")
        ax1.set_title("ground track")
        ax1.legend(fontsize=8)
        ax2 = self.fig.add_subplot(1, 2, 2)
        steps = np.arange(len(ys)) * self.task.dt_s
        ax2.plot(steps, tr["altitude_km"], color="tab:blue")
        ax2.axhline(tr["target_altitude_km"], color="tab:red", lw=1.0, ls="--", label="gate")
        if u is not None:
            alpha = float(u[0])
            ax2.annotate("", xy=(steps[-1] + 20.0 * math.cos(alpha),
                                 tr["altitude_km"][-1] + 1.0 * math.sin(alpha)),
                         xytext=(steps[-1], tr["altitude_km"][-1]),
                         arrowprops=dict(color="tab:red", width=1.2, headwidth=5))
        ax2.set_xlabel("time (s)")
        ax2.set_ylabel("altitude (km)")
        ax2.set_title("altitude, thrust elevation")
        ax2.legend(fontsize=8)
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
