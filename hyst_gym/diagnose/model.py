"""The fitted model: hysteresis + transducer + optional extension, with named parameters.

Base structures (``transducer``):

* ``"none"`` -- magnetization only (no displacement channel to explain);
* ``"first_order"`` -- displacement ``y' = -lam*y + nu*(M - M0)`` (scalar plant, paper §4.1);
* ``"lumped"`` -- linearized lumped model (13) about a bias magnetization M0:
  ``x'' + chat*x' + khat*x = zetahat*(M - M0)``;
* ``"lumped_nonlinear"`` -- nonlinear lumped model (12): ``x'' + chat*x' + khat*x = zeta2*(M^2 - M0^2)``;
* ``"fem"`` -- the finite-element rod (10) of :class:`hyst_gym.physics.fem.FEMRod`
  (``FEM_ELEMENTS`` elements, paper §2.2 rod data) linearized about M0: tip force
  ``zeta_fem*(M - M0)`` (zeta_fem = 2*zeta*M0 in N per A/m); with ``fit_mechanics`` the
  Young's modulus ``Y``, the tip mass ``ML`` and the Kelvin-Voigt damping ``cD`` are fitted
  too (they set the rod's modes), else they stay at RodParams()'s values.

Extensions (the mismatch tool's vocabulary), each with named physical parameters and each equal to
the base model when those parameters vanish:

==============================  ============================================================
``field_bias``                  ``H0`` (A/m) added to the recorded field
``eddy_current``                ``k_e`` (s): ``H_eff = H - k_e*dM/dt``
``thermal_drift``               ``heating`` (K/s per (A/m)^2), ``tau_th`` (s) and
                                ``heating_exponent`` p: coil temperature rise driven by
                                heating*h_ref^2*(|H|/h_ref)^p (p = 2: Joule heating; h_ref the RMS
                                field), ``a(T) = a*T/T_amb`` (4) (slope a/T_amb),
                                ``beta_Ms`` (1/K): ``Ms(T) = Ms*(1 - beta_Ms*(T - T_amb))``
``sensor_lag``                  ``tau_m``, ``tau_x`` (s): first-order sensor lags
``quadratic_magnetostriction``  ``zeta_q``: forcing ``zetahat*(M-M0) + zeta_q*(M-M0)^2``
                                (the M^2 law of (12) about a bias M0 gives zeta_q = zetahat/(2*M0);
                                a pure M^2 law has zetahat -> 0 with zeta_q finite)
``rod_dynamics``                ``f2`` (Hz), ``damping2`` (damping ratio) and ``g2``: a second
                                longitudinal rod mode (10) in parallel with the lumped one; g2
                                is its static gain relative to the first
``delta_e``                     ``delta_e``, ``delta_e_linear``: the Delta-E effect, a stiffness
                                that follows the magnetization, a quadratic in m = M/Ms:
                                ``khat*(1 + delta_e*(m^2 - m0^2) + delta_e_linear*(m - m0))``
                                (Terfenol-D stiffens toward saturation; Clark's Delta-E). The
                                family holds Clark's M^2 law (delta_e_linear = 0) and a law in
                                (M - Mb)^2 about another centre Mb (delta_e_linear = -2*delta_e*Mb/Ms)
``anhysteretic_shape``          the other anhysteretic curve (Ising <-> Langevin)
``input_map``                   ``input_quadratic``, ``input_cubic``, ``input_saturation``,
                                ``input_saturation_negative``: the field is a static map of the
                                recorded one, ``H = H_rec*(1 + q*u + c*u^2)/sqrt(1 + s*u^2)`` with
                                u = H_rec/max|H_rec| and s = input_saturation for u >= 0,
                                input_saturation_negative for u < 0 (a saturating amplifier: s > 0 or
                                c < 0; one with unequal rails: the two s; an asymmetric gain: q)
``sensor_map``                  ``sensor_quadratic_<ch>``, ``sensor_cubic_<ch>``: each output sensor
                                has a static nonlinearity, ``y_rec = y + s*(q2*v^2 + q3*v^3)`` with
                                v = (y - centre)/s over the recorded channel's range (half-span s)
``sensor_drift``                ``drift_linear_<ch>``, ``drift_quadratic_<ch>``: a slow additive drift
                                of each sensor's offset since the record's start (the sensor zeroed
                                there), ``s*(d1*f + d2*f^2)`` with f the record's time mapped to
                                [0, 1]
``mains_pickup``                ``mains_cos_<ch>``, ``mains_sin_<ch>``, ``mains3_cos_<ch>``,
                                ``mains3_sin_<ch>`` at ``mains_hz`` (50 or 60 Hz, chosen from the
                                base model's residual): additive pickup of the mains and its third
                                harmonic, in units of the channel's half-span
==============================  ============================================================

Each extension fills one *slot* of the model chain (:data:`EFFECT_SLOTS`): the input map, the
anhysteretic curve, the time variation of the material, the rate dependence, the
magnetostriction law, the stiffness, the mechanical modes, the sensor's dynamics or the sensor's
static map, the sensor's offset and pickup. The flexible families (``delta_e``, the heating law of
``thermal_drift``, ``input_map``, ``sensor_map``, ``sensor_drift``) hold the textbook law as a special
case and other laws of the same slot besides (issue 22).

The fitted coordinates are ``ln(value)`` for the positive scale parameters and
``value/scale`` for the others; the feedback is fitted as ``rho = alpha*Man'(0)`` (the
dimensionless mean-field gain, ``alpha*Ms/a`` for Ising, ``alpha*Ms/(3a)`` for Langevin).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..physics.fem import FEMRod
from ..physics.constants import PAPER_DAMPING, PAPER_STIFFNESS
from ..physics.transducers import RodParams
from .kernels import (AMBIENT_TEMPERATURE, MAGNETIC_COLUMNS, first_order_system, lti_response,
                      second_order_system, simulate_members, step_classes, step_lti,
                      varying_stiffness_response)
from .recording import Recording

TRANSDUCERS = ("none", "first_order", "lumped", "lumped_nonlinear", "fem")
EFFECTS = ("thermal_drift", "eddy_current", "quadratic_magnetostriction", "rod_dynamics",
           "sensor_lag", "field_bias", "anhysteretic_shape", "delta_e", "small_loop", "input_map", "sensor_map",
           "sensor_drift", "mains_pickup")
#: The slot of the model chain each extension fills, in an engineer's words (issue 22).
EFFECT_SLOTS = {
    "field_bias": "input map (recorded to true field): an offset",
    "input_map": "input map (recorded to true field): a static nonlinearity, e.g. a saturating amplifier",
    "anhysteretic_shape": "anhysteretic curve",
    "small_loop": "anhysteretic curve at low field (reversible susceptibility)",
    "thermal_drift": "time variation of the material parameters (a(t), Ms(t))",
    "eddy_current": "rate dependence",
    "quadratic_magnetostriction": "magnetostriction law",
    "delta_e": "stiffness (it follows the magnetization)",
    "rod_dynamics": "mechanical dynamics (a second mode)",
    "sensor_lag": "sensor dynamics (a lag)",
    "sensor_map": "sensor static map (a nonlinearity)",
    "sensor_drift": "sensor offset (a slow drift)",
    "mains_pickup": "sensor pickup (mains interference at 50/60 Hz)",
}
#: Additive sensor terms per output channel: slow offset drift and mains pickup.
DRIFT_NAMES = {"magnetization": ("drift_linear_m", "drift_quadratic_m"),
               "displacement": ("drift_linear_x", "drift_quadratic_x")}
MAINS_NAMES = {ch: tuple(f"{term}_{ch[0]}" for term in ("mains_cos", "mains_sin", "mains3_cos", "mains3_sin"))
               for ch in ("magnetization", "displacement")}
#: Mains pickup needs this many cycles in the record (a sinusoid of known frequency is fixed by a few)
#: and its third harmonic below the Nyquist frequency.
MAINS_MIN_CYCLES = 3
#: Sensor-map parameters per output channel.
SENSOR_MAP_NAMES = {"magnetization": ("sensor_quadratic_m", "sensor_cubic_m"),
                    "displacement": ("sensor_quadratic_x", "sensor_cubic_x")}
#: Parameters each extension adds (anhysteretic_shape adds none: it swaps the curve).
EFFECT_PARAMETERS = {
    "field_bias": ("H0",),
    "eddy_current": ("k_e",),
    "thermal_drift": ("heating", "tau_th", "beta_Ms", "heating_exponent"),
    "sensor_lag": ("tau_m", "tau_x"),
    "quadratic_magnetostriction": ("zeta_q",),
    # damping2, not zeta2: zeta2 is the M^2 gain of lumped_nonlinear (12)
    "rod_dynamics": ("f2", "damping2", "g2"),
    "anhysteretic_shape": (),
    "delta_e": ("delta_e", "delta_e_linear"),
    "small_loop": ("chi_r",),
    "input_map": ("input_quadratic", "input_cubic", "input_saturation", "input_saturation_negative"),
    "sensor_map": SENSOR_MAP_NAMES["magnetization"] + SENSOR_MAP_NAMES["displacement"],
    "sensor_drift": DRIFT_NAMES["magnetization"] + DRIFT_NAMES["displacement"],
    "mains_pickup": ("mains_hz",) + MAINS_NAMES["magnetization"] + MAINS_NAMES["displacement"],
}
#: Paper values of the lumped coefficients (13).
PAPER_CHAT = PAPER_DAMPING     # 1/s
PAPER_KHAT = PAPER_STIFFNESS   # 1/s^2
PAPER_MS = 7.65e5       # A/m
#: Default tolerance on the lumped mechanics (khat, chat): the fit keeps each within a factor
#: of this of its nominal value (the paper's (13), or ``khat``/``chat`` in the recording's
#: sidecar). A rod's data sheet pins its resonance far better than 1.5x; a looser prior lets
#: the base model absorb a sensor lag or a rod mode by moving its resonance (issue 12).
MECHANICS_TOLERANCE = 1.5
#: Elements of the ``fem`` base model's rod: its first two modes within ~1 % of a fine mesh.
FEM_ELEMENTS = 8
#: Rod data the ``fem`` base model fits (the others stay at RodParams()).
FEM_ROD_NAMES = ("Y", "ML", "cD", "cL")


@dataclass(frozen=True)
class Parameter:
    """One model parameter: physical value, bounds, unit, whether it is fitted."""

    name: str
    value: float
    lower: float
    upper: float
    unit: str
    log: bool = False
    free: bool = True
    scale: float = 1.0  # fitted coordinate is value/scale for linear parameters

    def to_x(self, value):
        return np.log(value) if self.log else value / self.scale

    def from_x(self, x):
        return float(np.exp(x)) if self.log else float(x * self.scale)

    @property
    def x_bounds(self):
        return self.to_x(self.lower), self.to_x(self.upper)


@dataclass(frozen=True)
class Structure:
    """What is being fitted: transducer, anhysteretic curve, extension, options."""

    transducer: str = "lumped"
    anhysteretic: str = "ising"
    extension: str | None = None
    fit_mechanics: bool = True
    mechanics_tolerance: float = MECHANICS_TOLERANCE

    def __post_init__(self):
        if self.transducer not in TRANSDUCERS:
            raise ValueError(f"model must be one of {', '.join(TRANSDUCERS)}, got {self.transducer!r}")
        if self.anhysteretic not in ("ising", "langevin"):
            raise ValueError(f"anhysteretic must be 'ising' or 'langevin', got {self.anhysteretic!r}")
        if self.extension is not None and self.extension not in EFFECTS:
            raise ValueError(f"unknown effect {self.extension!r}; expected one of {', '.join(EFFECTS)}")
        if not (self.mechanics_tolerance >= 1.0):
            raise ValueError(f"mechanics_tolerance must be a factor >= 1, got {self.mechanics_tolerance!r}")

    @property
    def curve(self) -> str:
        if self.extension == "anhysteretic_shape":
            return "langevin" if self.anhysteretic == "ising" else "ising"
        return self.anhysteretic


def slope_factor(curve: str) -> float:
    """Man'(0)*a/Ms: 1 for Ising, 1/3 for Langevin."""
    return 1.0 if curve == "ising" else 1.0 / 3.0


class Model:
    """A parametrized forward model of one recording.

    ``parameters`` is an ordered dict name -> :class:`Parameter`; :meth:`predict` maps a
    dict of physical values to the predicted output channels.
    """

    def __init__(self, recording: Recording, structure: Structure, parameters: dict,
                 max_field_step: float):
        self.recording = recording
        self.structure = structure
        self.parameters = dict(parameters)
        self.max_field_step = float(max_field_step)
        self._classes = step_classes(recording.time)
        self.channels = recording.channels
        if structure.transducer == "none" and "displacement" in self.channels:
            self.channels = tuple(c for c in self.channels if c != "displacement")

    # ---- parameter vectors
    @property
    def free_names(self):
        return [n for n, p in self.parameters.items() if p.free]

    def values(self) -> dict:
        return {n: p.value for n, p in self.parameters.items()}

    def x_from_values(self, values) -> np.ndarray:
        return np.array([self.parameters[n].to_x(values[n]) for n in self.free_names])

    def values_from_x(self, x) -> dict:
        values = self.values()
        for n, xi in zip(self.free_names, x):
            values[n] = self.parameters[n].from_x(xi)
        return values

    def with_values(self, values: dict) -> "Model":
        params = {n: replace(p, value=float(np.clip(values.get(n, p.value), p.lower, p.upper)))
                  for n, p in self.parameters.items()}
        return Model(self.recording, self.structure, params, self.max_field_step)

    # ---- forward model
    def magnetic_row(self, values) -> np.ndarray:
        curve = self.structure.curve
        a, Ms = values["a"], values["Ms"]
        alpha = values["rho"] * a / (Ms * slope_factor(curve))
        row = dict(a=a, k=values["k"], alpha=alpha, Ms=Ms, c=values["c"], H0=values.get("H0", 0.0),
                   k_e=values.get("k_e", 0.0), heating=values.get("heating", 0.0),
                   tau_th=values.get("tau_th", 1.0), beta_Ms=values.get("beta_Ms", 0.0),
                   chi_r=values.get("chi_r", 0.0), heating_exponent=values.get("heating_exponent", 2.0))
        return np.array([row[c] for c in MAGNETIC_COLUMNS])

    def magnetization(self, values_list) -> np.ndarray:
        """Simulated M (A/m) for each values dict: shape (T, len(values_list))."""
        rows = np.array([self.magnetic_row(v) for v in values_list])
        kind = 0 if self.structure.curve == "ising" else 1
        maps = np.array([[v.get(n, 0.0) for n in EFFECT_PARAMETERS["input_map"]] for v in values_list])
        out = np.empty((self.recording.size, len(values_list)))
        # members that share an input map share one field (one bank call per distinct map)
        for shape in np.unique(maps, axis=0):
            group = np.flatnonzero(np.all(maps == shape, axis=1))
            unique, inverse = np.unique(rows[group], axis=0, return_inverse=True)
            field = mapped_field(self.recording.field, *shape)
            simulated = simulate_members(self.recording.time, field, np.ascontiguousarray(unique), kind,
                                         self.max_field_step, AMBIENT_TEMPERATURE)
            out[:, group] = simulated[:, np.asarray(inverse).reshape(-1)]
        return out

    def predict(self, values, magnetization=None) -> dict:
        """Predicted channels for one values dict (``magnetization`` may be passed if known)."""
        if magnetization is None:
            magnetization = self.magnetization([values])[:, 0]
        out = {}
        time = self.recording.time
        if "magnetization" in self.channels:
            out["magnetization"] = self._sensor_terms("magnetization", values, _lag(
                time, magnetization, values.get("tau_m", 0.0), self._classes))
        if "displacement" in self.channels:
            out["displacement"] = self._sensor_terms("displacement", values, _lag(
                time, self.displacement(values, magnetization), values.get("tau_x", 0.0), self._classes))
        return out

    def _sensor_terms(self, channel, values, signal):
        """What the sensor adds to the true output: its static map (``sensor_map``), a slow offset drift
        (``sensor_drift``) and mains pickup (``mains_pickup``); the identity when their coefficients vanish."""
        quadratic, cubic = (values.get(n, 0.0) for n in SENSOR_MAP_NAMES[channel])
        drift = [values.get(n, 0.0) for n in DRIFT_NAMES[channel]]
        mains = [values.get(n, 0.0) for n in MAINS_NAMES[channel]]
        if quadratic == 0.0 and cubic == 0.0 and not any(drift) and not any(mains):
            return signal
        centre, half_span = channel_range(self.recording.output(channel))
        v = (signal - centre) / half_span
        out = signal + half_span * (quadratic * v ** 2 + cubic * v ** 3)
        if any(drift):
            fraction = self._record_fraction
            out = out + half_span * (drift[0] * fraction + drift[1] * fraction ** 2)
        if any(mains):
            phase = 2 * np.pi * values["mains_hz"] * self.recording.time
            out = out + half_span * (mains[0] * np.cos(phase) + mains[1] * np.sin(phase)
                                     + mains[2] * np.cos(3 * phase) + mains[3] * np.sin(3 * phase))
        return out

    @property
    def _record_fraction(self):
        """The record's time mapped to [0, 1]: the sensor drift's variable, 0 where the record starts."""
        time = self.recording.time
        return (time - time[0]) / (float(time[-1] - time[0]) or 1.0)

    def displacement(self, values, magnetization) -> np.ndarray:
        transducer = self.structure.transducer
        M0 = values["M0"]
        if transducer == "lumped_nonlinear":
            forcing = magnetization ** 2 - M0 ** 2
            gain = values["zeta2"]
        else:
            deviation = magnetization - M0
            gain = values[GAIN_NAMES[transducer]]
            # quadratic_magnetostriction: a second gain on (M - M0)^2 (kappa = zeta_q/gain)
            forcing = deviation + (values.get("zeta_q", 0.0) / gain) * deviation ** 2 if gain else deviation
        if transducer == "fem":
            return _fem_tip_displacement(self.recording.time, forcing, gain, values, self._classes)
        delta_e, delta_e_linear = values.get("delta_e", 0.0), values.get("delta_e_linear", 0.0)
        if (delta_e != 0.0 or delta_e_linear != 0.0) and transducer in ("lumped", "lumped_nonlinear"):
            relative_stiffness = relative_stiffness_change(magnetization, values)
            return varying_stiffness_response(self.recording.time, gain * forcing, relative_stiffness,
                                              values["khat"], values["chat"], classes=self._classes)
        if transducer == "first_order":
            A, B, C = first_order_system(values["lam"], gain)
        elif transducer in ("lumped", "lumped_nonlinear"):
            A, B, C = second_order_system(values["khat"], values["chat"], gain)
        g2 = values.get("g2", 0.0)
        if g2 != 0.0 and transducer != "first_order":
            omega = 2 * np.pi * values["f2"]
            stiffness = values["khat"]
            A2, B2, C2 = second_order_system(omega ** 2, 2 * values["damping2"] * omega,
                                             g2 * gain * omega ** 2 / stiffness)
            A = np.block([[A, np.zeros((2, 2))], [np.zeros((2, 2)), A2]])
            B = np.concatenate([B, B2])
            C = np.concatenate([C, C2])
        return lti_response(self.recording.time, forcing, A, B, C, start="steady", classes=self._classes)


def relative_stiffness_change(magnetization, values):
    """The Delta-E family's relative stiffness change khat(M)/khat - 1 (1) at ``magnetization`` (A/m):
    ``delta_e*(m^2 - m0^2) + delta_e_linear*(m - m0)``, m = M/Ms, zero at the bias M0."""
    m, m0 = magnetization / values["Ms"], values["M0"] / values["Ms"]
    return values.get("delta_e", 0.0) * (m ** 2 - m0 ** 2) + values.get("delta_e_linear", 0.0) * (m - m0)


def mapped_field(field, quadratic, cubic, saturation, saturation_negative):
    """The ``input_map`` family: the true field (A/m) for the recorded ``field`` (A/m),
    ``H*(1 + quadratic*u + cubic*u^2)/sqrt(1 + s*u^2)`` with u = H/max|H| and s = ``saturation``
    where u >= 0, ``saturation_negative`` where u < 0: a polynomial and an algebraic sigmoid (close to
    tanh) in one family, the identity when all four vanish.

    Why two saturations: an amplifier's rails are often unequal, so it saturates at another field on
    each side; the two sides join with equal value and slope at u = 0 (s*u^2 has zero slope there),
    and each side is monotone for any s >= 0 (slope (1 + s*u^2)**-1.5 at q = c = 0), where a
    polynomial asymmetry (q) large enough to mimic unequal rails would fold back."""
    if quadratic == 0.0 and cubic == 0.0 and saturation == 0.0 and saturation_negative == 0.0:
        return field
    u = field / (float(np.max(np.abs(field))) or 1.0)
    s = np.where(u >= 0.0, saturation, saturation_negative)
    return np.ascontiguousarray(field * (1.0 + quadratic * u + cubic * u ** 2) / np.sqrt(1.0 + s * u ** 2))


def channel_range(signal):
    """(centre, half-span) of a recorded channel: the frame of the ``sensor_map`` polynomial."""
    lo, hi = float(np.min(signal)), float(np.max(signal))
    return 0.5 * (lo + hi), (0.5 * (hi - lo) or 1.0)


#: Name of the displacement gain of each base transducer.
GAIN_NAMES = {"first_order": "nu", "lumped": "zetahat", "lumped_nonlinear": "zeta2", "fem": "zeta_fem"}


def fem_rod(values) -> FEMRod:
    """The ``fem`` base model's rod for a values dict (fitted Y, ML, cD where present)."""
    rod = RodParams(**{n: values[n] for n in FEM_ROD_NAMES if n in values})
    return FEMRod(rod=rod, n_elements=FEM_ELEMENTS)


def _fem_tip_displacement(time, forcing, gain, values, classes):
    """Tip displacement (m) of the FEM rod (10) under the tip force ``gain*forcing`` (N),
    starting at the static equilibrium of the first sample. :meth:`FEMRod.discretize` gives
    the exact first-order-hold update, one matrix exponential per distinct step length; the
    steps run in the compiled loop of :func:`~hyst_gym.diagnose.kernels.lti_response`."""
    fem = fem_rod(values)
    steps, index = classes
    discrete = [fem.discretize(float(dt)) for dt in steps]
    phis = np.array([d.phi for d in discrete])
    gamma0s = np.array([d.gamma0 for d in discrete])
    gamma1s = np.array([d.gamma1 for d in discrete])
    drive = gain * np.ascontiguousarray(forcing, dtype=np.float64)
    output = np.zeros(2 * fem.n_elements)
    output[discrete[0].output_index] = 1.0
    state0 = discrete[0].static_response * drive[0]
    return step_lti(drive, index, phis, gamma0s, gamma1s, output, state0)


def _lag(time, signal, tau, classes):
    """First-order sensor lag ``tau*y' = u - y`` (tau in s), starting settled."""
    if tau <= 0.0:
        return signal
    return lti_response(time, signal, [[-1.0 / tau]], [1.0 / tau], [1.0], start="steady", classes=classes)


def noise_level(signal) -> float:
    """Robust white-noise standard deviation from second differences (MAD / sqrt(6)).

    Smooth signal content barely enters second differences at high sampling rates, so this
    estimates the sensor noise of a densely sampled channel; floored at 1e-6 of the range.
    """
    d2 = np.diff(np.asarray(signal, dtype=np.float64), 2)
    sigma = 1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0)
    span = float(np.ptp(signal)) or 1.0
    return float(max(sigma, 1e-6 * span))


def base_parameters(recording: Recording, structure: Structure) -> dict:
    """Initial values and bounds of the base model's parameters, scaled to the recording."""
    field = recording.field
    h_max = float(np.max(np.abs(field))) or 1.0
    duration = float(recording.time[-1] - recording.time[0])
    dt = float(np.median(np.diff(recording.time)))
    has_m = recording.magnetization is not None
    m_max = float(np.max(np.abs(recording.magnetization))) if has_m else PAPER_MS * 0.8
    m_max = max(m_max, 1e-9)
    params = {
        "a": Parameter("a", h_max / 5, h_max / 2000, 20 * h_max, "A/m", log=True),
        "k": Parameter("k", h_max / 20, h_max / 1e5, 3 * h_max, "A/m", log=True),
        "rho": Parameter("rho", 0.0, -5.0, 0.99, "1 (alpha*Man'(0))", scale=0.5),
        "Ms": Parameter("Ms", 1.3 * m_max, 0.7 * m_max, 30 * m_max, "A/m", log=True, free=has_m),
        "c": Parameter("c", 0.3, 0.0, 0.95, "1", scale=0.2),
    }
    if not has_m:
        params["Ms"] = Parameter("Ms", PAPER_MS, PAPER_MS / 2, PAPER_MS * 2, "A/m", log=True, free=False)
    transducer = structure.transducer
    if "displacement" in recording.channels and transducer != "none":
        x_span = float(np.ptp(recording.displacement)) or 1e-9
        m_scale = params["Ms"].value
        params["M0"] = Parameter("M0", 0.0, -2 * m_scale, 2 * m_scale, "A/m", scale=0.1 * m_scale)
        if transducer == "fem":
            rod = RodParams()
            fix = not structure.fit_mechanics
            params["Y"] = Parameter("Y", rod.Y, rod.Y / 3, rod.Y * 3, "Pa", log=True, free=not fix)
            params["ML"] = Parameter("ML", rod.ML, 1e-3, 20.0, "kg", log=True, free=not fix)
            params["cD"] = Parameter("cD", rod.cD, 1e3, 1e8, "Pa s", log=True, free=not fix)
            # the tip damper too: with a heavy tip mass it sets the first mode's damping, which the
            # distributed (Kelvin-Voigt) damping cD can only reach by over-damping the higher modes
            params["cL"] = Parameter("cL", rod.cL, 1.0, 1e6, "N s/m", log=True, free=not fix)
            zeta = rod.lumped_stiffness * x_span / m_scale
            params["zeta_fem"] = Parameter("zeta_fem", zeta, -1e4 * zeta, 1e4 * zeta, "N per A/m", scale=zeta)
        elif transducer == "first_order":
            params["lam"] = Parameter("lam", 100.0, 0.01 / duration, 0.5 / dt, "1/s", log=True)
            nu = 100.0 * x_span / m_scale
            params["nu"] = Parameter("nu", nu, -1e3 * nu, 1e3 * nu, "m/s per A/m", scale=nu)
        else:
            fix = not structure.fit_mechanics
            tolerance = structure.mechanics_tolerance
            khat = float(recording.metadata.get("khat", PAPER_KHAT))
            chat = float(recording.metadata.get("chat", PAPER_CHAT))
            params["khat"] = Parameter("khat", khat, khat / tolerance, khat * tolerance, "1/s^2",
                                       log=True, free=not fix)
            params["chat"] = Parameter("chat", chat, chat / tolerance, chat * tolerance, "1/s",
                                       log=True, free=not fix)
            if transducer == "lumped_nonlinear":
                zeta2 = PAPER_KHAT * x_span / m_scale ** 2
                params["zeta2"] = Parameter("zeta2", zeta2, -1e4 * zeta2, 1e4 * zeta2, "m/s^2 per (A/m)^2",
                                            scale=zeta2)
            else:
                zeta = PAPER_KHAT * x_span / m_scale
                params["zetahat"] = Parameter("zetahat", zeta, -1e4 * zeta, 1e4 * zeta, "m/s^2 per A/m",
                                              scale=zeta)
    return params


def extension_parameters(recording: Recording, structure: Structure, base_values: dict) -> dict:
    """Initial values and bounds of the parameters ``structure.extension`` adds."""
    effect = structure.extension
    field = recording.field
    time = recording.time
    h_max = float(np.max(np.abs(field))) or 1.0
    duration = float(time[-1] - time[0])
    dt = float(np.median(np.diff(time)))
    rate = np.abs(np.diff(field)) / np.diff(time)
    out = {}
    if effect == "field_bias":
        out["H0"] = Parameter("H0", 0.0, -h_max, h_max, "A/m", scale=0.01 * h_max)
    elif effect == "eddy_current":
        ms = base_values.get("Ms", PAPER_MS)
        dm_dt = ms * float(np.percentile(rate, 95)) / h_max + 1e-30
        upper = 2.0 * h_max / dm_dt
        out["k_e"] = Parameter("k_e", 1e-3 * upper, 0.0, upper, "s", scale=1e-2 * upper)
    elif effect == "thermal_drift":
        mean_sq = float(np.mean(field ** 2)) or 1.0
        upper = 300.0 / (mean_sq * duration)  # at most ~300 K of heating over the record
        out["heating"] = Parameter("heating", 0.01 * upper, 0.0, upper, "K/s per (A/m)^2", scale=0.01 * upper)
        out["tau_th"] = Parameter("tau_th", duration, 5 * dt, 1e3 * duration, "s", log=True)
        out["beta_Ms"] = Parameter("beta_Ms", 0.0, -0.01, 0.01, "1/K", scale=1e-3)
        # the family's heating law: drive ~ |H|^p (Joule heating of a current-driven coil: p = 2;
        # core or hysteresis loss: p between 1 and 3)
        out["heating_exponent"] = Parameter("heating_exponent", 2.0, 0.5, 4.0, "1", scale=0.5)
    elif effect == "sensor_lag":
        for name, channel in (("tau_m", "magnetization"), ("tau_x", "displacement")):
            free = channel in recording.channels and (channel == "magnetization" or structure.transducer != "none")
            out[name] = Parameter(name, dt if free else 0.0, 0.0, 0.05 * duration, "s", scale=dt, free=free)
    elif effect == "quadratic_magnetostriction":
        m_span = base_values.get("Ms", PAPER_MS)
        gain = abs(next((base_values[g] for g in ("zetahat", "nu", "zeta_fem") if g in base_values), 1.0)) or 1.0
        out["zeta_q"] = Parameter("zeta_q", 0.0, -1e3 * gain / m_span, 1e3 * gain / m_span,
                                  "gain units per A/m", scale=0.1 * gain / m_span)
    elif effect == "delta_e":
        out["delta_e"] = Parameter("delta_e", 0.0, -0.5, 3.0, "1 (relative stiffness change, M = 0 to Ms)",
                                   scale=0.1)
        out["delta_e_linear"] = Parameter("delta_e_linear", 0.0, -3.0, 3.0,
                                          "1 (relative stiffness change per unit M/Ms)", scale=0.1)
    elif effect == "input_map":
        # monotone on |u| <= 1 needs 1 + 2*q*u + 3*c*u^2 > 0: c >= -1/3 at q = 0 (a tanh's cubic term)
        out["input_quadratic"] = Parameter("input_quadratic", 0.0, -0.5, 0.5, "1 (per unit H/max|H|)", scale=0.05)
        out["input_cubic"] = Parameter("input_cubic", 0.0, -0.33, 1.0, "1 (per unit (H/max|H|)^2)", scale=0.05)
        # gain at the peak field down to 1/sqrt(1 + 30) = 0.18 of the small-signal gain
        out["input_saturation_negative"] = Parameter("input_saturation_negative", 0.0, 0.0, 30.0,
                                                     "1 (per unit (H/max|H|)^2, where H < 0)", scale=0.5)
        out["input_saturation"] = Parameter("input_saturation", 0.0, 0.0, 30.0,
                                            "1 (per unit (H/max|H|)^2, where H >= 0)",
                                            scale=0.5)
    elif effect in ("sensor_drift", "mains_pickup"):
        if effect == "mains_pickup":
            out["mains_hz"] = Parameter("mains_hz", 50.0, 45.0, 65.0, "Hz", free=False)
        for channel, names in (DRIFT_NAMES if effect == "sensor_drift" else MAINS_NAMES).items():
            free = channel in recording.channels and (channel == "magnetization" or structure.transducer != "none")
            for name in names:
                out[name] = Parameter(name, 0.0, -1.0, 1.0, "1 (of the channel's half-span)", scale=0.01,
                                      free=free)
    elif effect == "sensor_map":
        for channel, names in SENSOR_MAP_NAMES.items():
            free = channel in recording.channels and (channel == "magnetization" or structure.transducer != "none")
            for name in names:
                out[name] = Parameter(name, 0.0, -0.5, 0.5, "1 (of the channel's half-span)", scale=0.05,
                                      free=free)
    elif effect == "small_loop":
        # a reversible susceptibility up to three times the anhysteretic's initial slope
        # Ms*slope_factor/a (fits to measured ferrite loops give 0.4-0.8 times it)
        initial_slope = (base_values.get("Ms", PAPER_MS) * slope_factor(structure.curve)
                         / base_values.get("a", h_max / 5))
        out["chi_r"] = Parameter("chi_r", 0.0, 0.0, 3.0 * initial_slope, "1 (reversible low-field susceptibility)",
                                 scale=0.1 * initial_slope)
    elif effect == "rod_dynamics":
        f1 = np.sqrt(base_values.get("khat", PAPER_KHAT)) / (2 * np.pi)
        nyquist = 0.5 / dt
        out["f2"] = Parameter("f2", min(5 * f1, 0.6 * nyquist), 1.2 * f1, 0.98 * nyquist, "Hz", log=True)
        out["damping2"] = Parameter("damping2", 0.05, 1e-3, 2.0, "1", log=True)
        out["g2"] = Parameter("g2", 0.0, -1.0, 1.0, "1 (static gain relative to mode 1)", scale=0.01)
    return out


def applicable_effects(recording: Recording, structure: Structure) -> list[str]:
    """Vocabulary effects that can show in this recording under this base structure."""
    has_x = "displacement" in recording.channels and structure.transducer not in ("none",)
    effects = ["thermal_drift", "eddy_current", "sensor_lag", "field_bias", "anhysteretic_shape", "small_loop",
               "input_map", "sensor_map", "sensor_drift"]
    duration = float(recording.time[-1] - recording.time[0])
    nyquist = 0.5 / float(np.median(np.diff(recording.time)))
    rated = recording.metadata.get("time_axis") != "synthetic"
    if duration * 50.0 >= MAINS_MIN_CYCLES and nyquist > 3 * 60.0 and rated:
        effects.append("mains_pickup")
    if has_x and structure.transducer != "lumped_nonlinear":
        effects.insert(2, "quadratic_magnetostriction")
    if has_x and structure.transducer in ("lumped", "lumped_nonlinear"):
        effects.insert(3, "rod_dynamics")
        effects.append("delta_e")
    return effects
