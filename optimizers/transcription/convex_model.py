"""The landing models as the SCvx solver sees them (:mod:`optimizers.transcription.convex`):
the control halves of :mod:`lunar_env.dynamics` in the thrust-vector variables (x, w, Γ), with
CasADi's exact Jacobians, the problem's constraints, and the map back to the model's control."""

from __future__ import annotations

import math

import numpy as np

from lunar_env import dynamics as dyn

from ..common.casadi_tools import casadi as _casadi

__all__ = ["ConvexModel"]


# ------------------------------------------------------------------------------------------
# The two models, as the solver sees them (control halves of lunar_env.dynamics)
# ------------------------------------------------------------------------------------------


class ConvexModel:
    """Dynamics in (x, w, Γ) from the shared equations, the problem's constraints, and the
    mapping back to the model's control. Built once per problem type and parameters."""

    def __init__(self, ocp) -> None:
        from ..problems.pinpoint import PinpointOCP
        from ..problems.planar_ocp import PlanarOCP

        ca = _casadi()
        self.ocp = ocp
        self.n_x = int(ocp.n_state)
        if isinstance(ocp, PlanarOCP):
            self.kind = "planar"
            self.d = 2
            p = ocp.params
            self.mass_index = dyn.M

            def f(x, u):
                return ca.vertcat(*dyn.planar_eom_terms(
                    x[dyn.R], x[dyn.VR], x[dyn.OMEGA], x[dyn.M], u[0], u[1], u[2],
                    p.thrust_nd, p.exhaust_velocity_nd))

            self.mass_min = float(ocp.dry_mass_nd)
            r_floor = float(ocp.scaling.length_nd(ocp.scenario.surface_radius_m))
            xs = ca.SX.sym("x", self.n_x)
            path = (xs[dyn.R], np.array([r_floor]), np.array([np.inf]))
        elif isinstance(ocp, PinpointOCP):
            self.kind = "pinpoint"
            self.d = 3
            p = ocp.params
            n = p.plane_normal
            self.mass_index = dyn.M3

            def f(x, u):
                return ca.vertcat(*dyn.moon3d_eom_terms(
                    x[dyn.X], x[dyn.Y], x[dyn.Z], x[dyn.VX], x[dyn.VY], x[dyn.VZ], x[dyn.M3],
                    u[0], u[1], u[2], u[3], p.thrust_nd, p.exhaust_velocity_nd,
                    p.spin_rate_nd, n[0], n[1], n[2]))

            self.mass_min = float(ocp.mass_min_nd)
            xs = ca.SX.sym("x", self.n_x)
            # the pinpoint path constraints are state-only; the control argument is unused
            path = ocp.path_constraints(xs, ca.SX.zeros(ocp.n_control))
        else:
            raise TypeError(f"SCvx solves a PlanarOCP or a PinpointOCP, got "
                            f"{type(ocp).__name__}")
        self.n_u = self.d + 1
        self.rhs = f
        # control set: ‖w‖ ≤ Γ ≤ 1, plus half-spaces a·(w, Γ) ≤ 0 for the 3D angle bounds
        self.halfspaces = self._angle_halfspaces()
        expr, lo, hi = path
        self.path_fn = ca.Function("path", [xs], [expr, ca.jacobian(expr, xs)])
        self.path_lo = np.asarray(lo, dtype=float)
        self.path_hi = np.asarray(hi, dtype=float)
        self.n_path = int(self.path_lo.size)
        xf = ca.SX.sym("xf", self.n_x)
        res = ocp.terminal_residual(xf)
        self.term_fn = ca.Function("term", [xf], [res, ca.jacobian(res, xf)])
        self.n_term = int(res.numel())

    def _angle_halfspaces(self) -> np.ndarray:
        """Rows a with a·(w, Γ) ≤ 0: [001]'s α ∈ [α₁, α₂], β ∈ [β₁, β₂] on a tight control
        (‖w‖ = Γ): w_r ≤ Γ sin α₂, −w_r ≤ −Γ sin α₁, and β within (β₁, β₂) about π as the
        wedge of the (along-track, cross-track) plane between the two bounding directions."""
        if self.kind != "pinpoint":
            return np.zeros((0, self.n_u))
        a1, a2 = self.ocp.alpha_bounds_rad
        b1, b2 = self.ocp.beta_bounds_rad
        if not (b2 - b1 < math.pi):
            raise ValueError(f"beta bounds {b1!r}..{b2!r} rad span π or more: not convex")
        rows = [[1.0, 0.0, 0.0, -math.sin(a2)], [-1.0, 0.0, 0.0, math.sin(a1)]]
        # a horizontal direction (cos β, sin β) lies in the wedge iff it is on the inner
        # side of both bounding rays: sin(β − β₁) ≥ 0 and sin(β₂ − β) ≥ 0
        rows.append([0.0, math.sin(b1), -math.cos(b1), 0.0])
        rows.append([0.0, -math.sin(b2), math.cos(b2), 0.0])
        return np.asarray(rows)

    def model_controls(self, u: np.ndarray) -> np.ndarray:
        """The model's control rows of (w, Γ) rows (n, d + 1): direction w/‖w‖ at throttle Γ.
        A zero thrust vector keeps the angle of the previous row (or braking)."""
        u = np.atleast_2d(u)
        out = np.empty((len(u), 2 if self.kind == "planar" else 3))
        for i, row in enumerate(u):
            w, g = row[:self.d], float(np.clip(row[self.d], 0.0, 1.0))
            if np.linalg.norm(w) < 1e-9:
                ang = out[i - 1, :-1] if i else (np.array([0.0]) if self.kind == "planar"
                                                 else np.array([0.0, math.pi]))
            elif self.kind == "planar":
                ang = np.array([math.atan2(w[0], w[1])])
            else:
                alpha = math.atan2(w[0], math.hypot(w[1], w[2]))
                beta = math.atan2(w[2], w[1]) % (2.0 * math.pi)
                ang = np.array([alpha, beta])
            out[i, :-1] = ang
            out[i, -1] = g
        return out


# ------------------------------------------------------------------------------------------
# The solver
# ------------------------------------------------------------------------------------------
