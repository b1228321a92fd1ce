"""Top view of the arm, the wall, the target and the tip trace, with a height gauge for q3.

Matplotlib draws into an Agg canvas, so ``rgb_array`` needs no display; ``human``
shows the same figure in a window where there is a display, and draws it off-screen where
there is none (the env says so once, at construction).
"""

from __future__ import annotations

import os
import sys

import numpy as np

from scara_gym.model.dynamics import elbow_position, tip_position
from scara_gym.model.params import ScaraParams


def has_display() -> bool:
    """Whether render_mode="human" can open a window (on Linux: DISPLAY or WAYLAND_DISPLAY is set)."""
    return not sys.platform.startswith("linux") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class ScaraRenderer:
    def __init__(self, params: ScaraParams, human: bool = False, size=(6.4, 4.8), dpi: int = 100) -> None:
        import matplotlib
        if human:
            import matplotlib.pyplot as plt
            self.figure = plt.figure(figsize=size, dpi=dpi)
            plt.ion()
            plt.show(block=False)
        else:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure
            self.figure = Figure(figsize=size, dpi=dpi)
            FigureCanvasAgg(self.figure)
        del matplotlib
        self.human = human
        self.params = params
        self._p = params.to_record()
        grid = self.figure.add_gridspec(1, 2, width_ratios=(5, 1))
        self.top = self.figure.add_subplot(grid[0])
        self.gauge = self.figure.add_subplot(grid[1])
        reach = params.arm.reach * 1.1
        self.top.set(xlim=(-reach, reach), ylim=(-reach, reach), aspect="equal", xlabel="x [m]", ylabel="y [m]")
        self.gauge.set(xlim=(0, 1), ylim=(-0.05, 0.45), xticks=[], ylabel="q3 [m]")
        self.gauge.yaxis.set_label_position("right")
        self.gauge.yaxis.tick_right()
        obs = params.obstacle
        self.wall_band = self.top.axvspan(obs.x_position - obs.critical_distance,
                                          obs.x_position + obs.critical_distance, color="0.88")
        self.wall = self.top.axvline(obs.x_position, color="k", lw=3)
        self.wall_height = self.gauge.axhline(obs.height, color="k", lw=2)
        (self.trace,) = self.top.plot([], [], color="tab:blue", lw=1, alpha=0.6)
        (self.arm,) = self.top.plot([], [], "-o", color="tab:gray", lw=6, ms=8)
        (self.target,) = self.top.plot([], [], "r*", ms=14)
        self.bar = self.gauge.bar([0.5], [0.0], width=0.6, color="tab:blue")[0]
        (self.target_height,) = self.gauge.plot([0.1, 0.9], [0, 0], "r-", lw=2)
        self.label = self.top.text(0.02, 0.98, "", transform=self.top.transAxes, va="top", family="monospace")

    def set_params(self, params: ScaraParams) -> None:
        """Draw an episode with other parameters (a randomized wall, other link lengths)."""
        if params is self.params:
            return
        self.params, self._p = params, params.to_record()
        obs = params.obstacle
        self.wall_band.remove()
        self.wall_band = self.top.axvspan(obs.x_position - obs.critical_distance,
                                          obs.x_position + obs.critical_distance, color="0.88")
        self.wall.set_xdata([obs.x_position, obs.x_position])
        self.wall_height.set_ydata([obs.height, obs.height])

    def draw(self, q, target, trace, obstacle: bool, critical: bool, time: float, collisions: int):
        elbow = elbow_position(q[0], self._p)
        tip = tip_position(q[0], q[1], q[2], self._p)
        self.arm.set_data([0.0, elbow[0], tip[0]], [0.0, elbow[1], tip[1]])
        trace = np.asarray(trace)
        self.trace.set_data(trace[:, 0], trace[:, 1])
        target_tip = tip_position(target[0], target[1], target[2], self._p)
        self.target.set_data([target_tip[0]], [target_tip[1]])
        for artist in (self.wall, self.wall_band, self.wall_height):
            artist.set_visible(obstacle)
        self.wall.set_color("tab:red" if critical else "k")
        self.bar.set_height(q[2])
        self.target_height.set_ydata([target[2], target[2]])
        self.label.set_text(f"t = {time:5.2f} s" + (f"   collisions: {collisions}" if collisions else ""))
        canvas = self.figure.canvas
        canvas.draw()
        if self.human:
            canvas.flush_events()
            return None
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()

    def close(self) -> None:
        if self.human:
            import matplotlib.pyplot as plt
            plt.close(self.figure)
        self.figure = None
