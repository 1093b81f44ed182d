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
                                ``beta_k``, ``beta_c`` (1/K): the pinning and the reversibility
                                move with it too, ``k(T) = k*(1 - beta_k*(T - T_amb))``,
                                ``c(T) = c*(1 - beta_c*(T - T_amb))`` (the plain heating law at 0)
``sensor_lag``                  ``tau_m``, ``tau_x``, ``tau2_m``, ``tau2_x`` (s): each output
                                sensor a second-order filter ``1/(1 + tau*s + tau2^2*s^2)``
                                (natural frequency 1/(2*pi*tau2), damping ratio tau/(2*tau2));
                                tau2 = 0 is the first-order lag
``quadratic_magnetostriction``  ``zeta_q``, ``zeta_4``: forcing ``zetahat*(M-M0) +
                                zeta_q*(M-M0)^2 + Ms*zeta_4*(m^4 - m0^4)``, m = M/Ms (the M^2 law
                                of (12) about a bias M0 gives zeta_q = zetahat/(2*M0); a pure M^2
                                law has zetahat -> 0 with zeta_q finite; the even term: a law that
                                saturates or rises faster than M^2)
``rod_dynamics``                ``f2`` (Hz), ``damping2`` (damping ratio) and ``g2``: a second
                                longitudinal rod mode (10) in parallel with the lumped one; g2
                                is its static gain relative to the first
``delta_e``                     ``delta_e``, ``delta_e_linear``, ``delta_e_cubic``,
                                ``delta_e_quartic``: the Delta-E effect, a stiffness that follows
                                the magnetization, a quartic in m = M/Ms: ``khat*(1 + delta_e*(m^2 -
                                m0^2) + delta_e_linear*(m - m0) + delta_e_cubic*(m^3 - m0^3)
                                + delta_e_quartic*(m^4 - m0^4))`` (Terfenol-D stiffens toward
                                saturation; Clark's Delta-E). The family holds Clark's M^2 law
                                (the other terms 0), a law in (M - Mb)^2 about another centre Mb
                                (delta_e_linear = -2*delta_e*Mb/Ms), laws about Mb that are not
                                parabolas there (delta_e_cubic) and a dip narrower than a parabola
                                (delta_e_quartic)
``anhysteretic_shape``          the other anhysteretic curve (Ising <-> Langevin), or a mixture:
                                ``mix_weight`` w and ``mix_a_ratio`` r, the magnetization
                                ``(1 - w)*M[other curve, a] + w*M[base curve, r*a]`` (two phases,
                                the same k, c, Ms and rho, each phase with its own feedback on its
                                own magnetization): w = 0 is the swap, w = 1 the
                                base curve; between them Brillouin-like curves, and a sharper or
                                softer knee (r < 1 or > 1); and ``knee_log_p`` = ln p, the knee
                                exponent of the family's Ising phase, ``tanh(|x|^p)^(1/p)``
                                (p = 1: the Ising curve; unit slope at 0 for every p; p > 1 a
                                sharper knee, p < 1 a softer one). With the Ising base, w = 1 and
                                p != 1 is the knee curve alone
``input_map``                   ``input_quadratic``, ``input_cubic``, ``input_saturation``,
                                ``input_saturation_negative``: the field is a static map of the
                                recorded one, ``H = H_rec*(1 + q*u + c*u^2)/sqrt(1 + s*u^2)`` with
                                u = H_rec/max|H_rec| and s = input_saturation for u >= 0,
                                input_saturation_negative for u < 0 (a saturating amplifier: s > 0 or
                                c < 0; one with unequal rails: the two s; an asymmetric gain: q)
``sensor_map``                  ``sensor_quadratic_<ch>``, ``sensor_cubic_<ch>``: each output sensor
                                has a static nonlinearity, ``y_rec = y + s*(q2*v^2 + q3*v^3)`` with
                                v = (y - centre)/s over the recorded channel's range (half-span s)
``sensor_drift``                ``drift_linear_<ch>``, ``drift_quadratic_<ch>``, ``drift_settling_<ch>``,
                                ``tau_drift`` (record lengths, shared): a slow additive drift of each
                                sensor's offset since the record's start (the sensor zeroed there),
                                ``s*(d1*f + d2*f^2 + d3*(1 - exp(-f/tau_drift)))`` with f the record's
                                time mapped to [0, 1]
``sensor_gain_drift``           ``gain_drift_linear_<ch>``, ``gain_drift_settling_<ch>``, ``tau_gain``
                                (record lengths, shared): a slow drift of each sensor's gain since
                                the record's start (calibrated there): the reading is
                                ``1 + g1*f + g2*(1 - exp(-f/tau_gain))`` times the true output (after
                                the static map), f as for ``sensor_drift``
``mains_pickup``                ``mains_cos_<ch>``, ``mains_sin_<ch>``, ``mains3_cos_<ch>``,
                                ``mains3_sin_<ch>`` at ``mains_hz`` (50 or 60 Hz, chosen from the
                                base model's residual): additive pickup of the mains and its third
                                harmonic, in units of the channel's half-span
==============================  ============================================================

Each extension fills one *slot* of the model chain (its ``slot`` in the registry, :mod:`.effects`): the input map, the
anhysteretic curve, the time variation of the material, the rate dependence, the
magnetostriction law, the stiffness, the mechanical modes, the sensor's dynamics or the sensor's
static map, the sensor's offset and pickup. The flexible families (``delta_e``, the heating law of
``thermal_drift``, ``input_map``, ``sensor_map``, ``sensor_drift``, ``sensor_gain_drift``) hold the textbook
law as a special case and other laws of the same slot besides.

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
from .effects import (DELTA_E_NAMES, DRIFT_NAMES, EFFECTS, EVEN_LAW_NAMES, EVEN_LAW_POWERS, GAIN_DRIFT_NAMES,
                      INPUT_DYNAMICS_NAMES, INPUT_MAP_NAMES, MAINS_MIN_CYCLES, MAINS_NAMES, PAPER_MS, SENSOR_MAP_NAMES,
                      applicable_effects, effect, extension_parameters, mapped_field)
from .kernels import (AMBIENT_TEMPERATURE, MAGNETIC_COLUMNS, PINNING_DRIFT_COLUMNS, first_order_system, lti_response,
                      heating_reference, knee_exponents, lane_passes, member_passes, second_order_system,
                      simulate_lanes,
                      simulate_members, step_classes, step_lti,
                      varying_stiffness_response)
from .parameter import Parameter, slope_factor
from .recording import Recording

TRANSDUCERS = ("none", "first_order", "lumped", "lumped_nonlinear", "fem")
# The vocabulary and each effect's parameters live in the registry (.effects); these names stay importable here.
__all__ = ["DRIFT_NAMES", "EFFECTS", "FEM_ELEMENTS", "FEM_ROD_NAMES", "GAIN_NAMES", "MAINS_MIN_CYCLES", "MAINS_NAMES",
           "MECHANICS_TOLERANCE", "Model", "PAPER_CHAT", "PAPER_KHAT", "PAPER_MS", "Parameter", "SENSOR_MAP_NAMES",
           "Structure", "TRANSDUCERS", "applicable_effects", "base_parameters", "channel_range", "extension_parameters",
           "fem_rod", "mapped_field", "noise_level", "relative_stiffness_change", "slope_factor"]
#: Paper values of the lumped coefficients (13).
PAPER_CHAT = PAPER_DAMPING     # 1/s
PAPER_KHAT = PAPER_STIFFNESS   # 1/s^2
#: Default tolerance on the lumped mechanics (khat, chat): the fit keeps each within a factor
#: of this of its nominal value (the paper's (13), or ``khat``/``chat`` in the recording's
#: sidecar). A rod's data sheet pins its resonance far better than 1.5x; a looser prior lets
#: the base model absorb a sensor lag or a rod mode by moving its resonance.
MECHANICS_TOLERANCE = 1.5
#: Elements of the ``fem`` base model's rod: its first two modes within ~1 % of a fine mesh.
FEM_ELEMENTS = 8
#: Rod data the ``fem`` base model fits (the others stay at RodParams()).
FEM_ROD_NAMES = ("Y", "ML", "cD", "cL")


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
        if self.extension is not None:
            effect(self.extension)  # a one-line error naming the vocabulary if it is not registered
        if not (self.mechanics_tolerance >= 1.0):
            raise ValueError(f"mechanics_tolerance must be a factor >= 1, got {self.mechanics_tolerance!r}")

    @property
    def curve(self) -> str:
        if self.extension is not None and effect(self.extension).swaps_curve:
            return "langevin" if self.anhysteretic == "ising" else "ising"
        return self.anhysteretic


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
        self._full_classes = self._classes  # the whole record's, also where :attr:`horizon` cuts _classes
        #: samples simulated from the record's start (None: all); see :meth:`up_to`
        self.horizon = None
        self.channels = recording.channels
        if structure.transducer == "none" and "displacement" in self.channels:
            self.channels = tuple(c for c in self.channels if c != "displacement")

    def up_to(self, samples: int) -> "Model":
        """This model simulating only the record's first ``samples`` samples (its predictions that long).

        Why: the fits read only the fitting block, the record's start, and every part of the model is causal
        (the hysteresis, the heating, the filters and the mechanics start at the first sample and look only
        back), so the samples after it need not be simulated. What the model takes from the whole record
        (the input map's and the sensor map's ranges, the heating's reference field, the drift's time
        fraction, the step classes) is still the whole record's: the predictions are those of the whole
        model, cut, to the last bit."""
        if not 1 <= samples <= self.recording.size:
            raise ValueError(f"samples must be in [1, {self.recording.size}], got {samples!r}")
        model = Model.__new__(Model)
        model.__dict__.update(self.__dict__)
        model.horizon = None if samples == self.recording.size else int(samples)
        steps, index = self._full_classes
        model._classes = (steps, index if model.horizon is None else index[:model.horizon - 1])
        return model

    @property
    def _time(self):
        """The sample times simulated (the whole record's, or its first :attr:`horizon`)."""
        return self.recording.time if self.horizon is None else self.recording.time[:self.horizon]

    def _cut(self, signal):
        return signal if self.horizon is None else np.ascontiguousarray(signal[:self.horizon])

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
        # the pinning's and the reversibility's time variation (thermal_drift), and the knee exponent of the Ising
        # curve (anhysteretic_shape; a Langevin curve has none): trailing columns the kernel reads
        knee = float(np.exp(values.get("knee_log_p", 0.0))) if curve == "ising" else 1.0
        # the heating network's second stage (THERMAL_LAG_COLUMNS: tau_th2 = 0 the one-stage law)
        return np.array([row[c] for c in MAGNETIC_COLUMNS] + [values.get(n, 0.0) for n in PINNING_DRIFT_COLUMNS]
                        + [knee, values.get("tau_th2", 0.0), values.get("thermal_share", 1.0)])

    def magnetization(self, values_list) -> np.ndarray:
        """Simulated M (A/m) for each values dict: shape (T, len(values_list))."""
        rows = np.array([self.magnetic_row(v) for v in values_list])
        kind = 0 if self.structure.curve == "ising" else 1
        time = self._time
        whole_time = self.recording.time
        # the input side: its static map and its dynamics (zeros: the recorded field itself), on the whole record
        # (the map's range is the whole record's) and then cut
        maps = np.array([[v.get(n, 0.0) for n in INPUT_MAP_NAMES + INPUT_DYNAMICS_NAMES] for v in values_list])
        shapes, map_of = np.unique(maps, axis=0, return_inverse=True)
        map_of = np.asarray(map_of).reshape(-1)
        fields = [mapped_field(input_dynamics(whole_time, self.recording.field, *shape[4:],
                                              classes=self._full_classes), *shape[:4]) for shape in shapes]
        references = np.array([heating_reference(np.ascontiguousarray(f)) for f in fields])
        fields = [self._cut(f) for f in fields]
        # each distinct (input map, magnetic row) simulated once
        unique, inverse = np.unique(np.column_stack([map_of, rows]), axis=0, return_inverse=True)
        inverse = np.asarray(inverse).reshape(-1)
        members = np.ascontiguousarray(unique[:, 1:])
        kneed = bool(np.any(knee_exponents(members) != 1.0))  # the knee family: lanes only
        if (len(fields) == 1 and member_passes(members) == 1 and not kneed
                and (self.horizon is None or not np.any(members[:, 7]))):
            # one bank under one field (the physics layer's bank kernel)
            simulated = simulate_members(time, np.ascontiguousarray(fields[0]), members, kind, self.max_field_step,
                                         AMBIENT_TEMPERATURE)
        else:
            # members under several fields, with eddy currents or heating, or on the knee family: one pass of
            # lanes, each its own field, substeps and curve, with the same numbers as alone (kernels.simulate_lanes)
            field_rows = np.ascontiguousarray(np.array(fields, dtype=np.float64).reshape(len(fields), -1))
            simulated = simulate_lanes(time, field_rows, np.ascontiguousarray(unique[:, 0].astype(np.int64)),
                                       members, references, kind,
                                       self.max_field_step, AMBIENT_TEMPERATURE)
        out = np.ascontiguousarray(simulated[:, inverse])
        return self._curve_mixture(values_list, out)

    def simulation_passes(self, values_list) -> int:
        """Compiled passes over the record that :meth:`magnetization` makes for ``values_list``
        (:func:`~.kernels.member_passes` per distinct input map, and the mixture's second phase): its cost,
        about the same for one member as for a bank of them."""
        rows = np.array([self.magnetic_row(v) for v in values_list])
        maps = np.array([[v.get(n, 0.0) for n in INPUT_MAP_NAMES + INPUT_DYNAMICS_NAMES] for v in values_list])
        shapes, map_of = np.unique(maps, axis=0, return_inverse=True)
        unique = np.unique(np.column_stack([np.asarray(map_of).reshape(-1), rows]), axis=0)
        passes = member_passes(unique[:, 1:])
        if len(shapes) > 1 or passes > 1 or np.any(knee_exponents(unique[:, 1:]) != 1.0):
            passes = lane_passes(unique.shape[0])
        mixed = [v for v in values_list if v.get("mix_weight", 0.0) != 0.0]
        if mixed:
            phase = Model(self.recording, replace(self.structure, extension=None), self.parameters,
                          self.max_field_step)
            passes += phase.simulation_passes([dict(v, a=v["a"] * v["mix_a_ratio"], mix_weight=0.0) for v in mixed])
        return passes

    def _curve_mixture(self, values_list, out):
        """The ``anhysteretic_shape`` family: ``(1 - w)*M[curve] + w*M[base curve, a*r]`` with w = ``mix_weight``
        and r = ``mix_a_ratio``, a second phase on the base model's curve with its own shape parameter (the
        other parameters, rho included, take the same values, but each phase is simulated with its own feedback on
        its own magnetization: the phases are not coupled); ``out`` itself (the plain swapped curve) where w = 0."""
        weights = [v.get("mix_weight", 0.0) for v in values_list]
        mixed = [i for i, w in enumerate(weights) if w != 0.0]
        if not mixed:
            return out
        phase = Model(self.recording, replace(self.structure, extension=None), self.parameters, self.max_field_step)
        phase = phase.up_to(out.shape[0])
        second = phase.magnetization([dict(values_list[i], a=values_list[i]["a"] * values_list[i]["mix_a_ratio"],
                                           mix_weight=0.0) for i in mixed])
        for column, i in enumerate(mixed):
            out[:, i] = (1.0 - weights[i]) * out[:, i] + weights[i] * second[:, column]
        return out

    def predict(self, values, magnetization=None) -> dict:
        """Predicted channels for one values dict (``magnetization`` may be passed if known)."""
        if magnetization is None:
            magnetization = self.magnetization([values])[:, 0]
        out = {}
        time = self._time
        if "magnetization" in self.channels:
            out["magnetization"] = self._sensor_terms("magnetization", values, sensor_dynamics(
                time, magnetization, values.get("tau_m", 0.0), values.get("tau2_m", 0.0), self._classes))
        if "displacement" in self.channels:
            out["displacement"] = self._sensor_terms("displacement", values, sensor_dynamics(
                time, self.displacement(values, magnetization), values.get("tau_x", 0.0), values.get("tau2_x", 0.0),
                self._classes))
        return out

    def _sensor_terms(self, channel, values, signal):
        """What the sensor adds to the true output: its static map (``sensor_map``), a slow offset drift
        (``sensor_drift``), a slow drift of its gain (``sensor_gain_drift``) and mains pickup (``mains_pickup``);
        the identity when their coefficients vanish."""
        quadratic, cubic = (values.get(n, 0.0) for n in SENSOR_MAP_NAMES[channel])
        drift = [values.get(n, 0.0) for n in DRIFT_NAMES[channel]]
        gain = [values.get(n, 0.0) for n in GAIN_DRIFT_NAMES[channel]]
        mains = [values.get(n, 0.0) for n in MAINS_NAMES[channel]]
        if quadratic == 0.0 and cubic == 0.0 and not any(drift) and not any(gain) and not any(mains):
            return signal
        ranges = self.__dict__.setdefault("_channel_ranges", {})  # the recorded channel's, once per model
        if channel not in ranges:
            ranges[channel] = channel_range(self.recording.output(channel))
        centre, half_span = ranges[channel]
        v = (signal - centre) / half_span
        out = signal + half_span * (quadratic * v ** 2 + cubic * v ** 3)
        if any(gain):
            # the sensor's gain drifts from its calibration at the record's start: it scales the whole reading
            # (a static map's output, before the offset and the pickup that add to it)
            out = gain_drift_factor(self._record_fraction, *gain, values["tau_gain"]) * out
        if any(drift):
            fraction = self._record_fraction
            out = out + half_span * (drift[0] * fraction + drift[1] * fraction ** 2)
            if drift[2]:  # the settling term (a warm-up), the gain drift's basis
                out = out + half_span * drift[2] * settling(fraction, values["tau_drift"])
        if any(mains):
            phase = 2 * np.pi * values["mains_hz"] * self._time
            out = out + half_span * (mains[0] * np.cos(phase) + mains[1] * np.sin(phase)
                                     + mains[2] * np.cos(3 * phase) + mains[3] * np.sin(3 * phase))
        return out

    @property
    def _record_fraction(self):
        """The record's time mapped to [0, 1]: the sensor drift's variable, 0 where the record starts."""
        time = self.recording.time
        return self._cut((time - time[0]) / (float(time[-1] - time[0]) or 1.0))

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
            even = {n: values.get(n, 0.0) for n in EVEN_LAW_NAMES}
            if any(even.values()) and gain:
                forcing = forcing + even_law_forcing(magnetization, values["Ms"], M0, even) / gain
        if transducer == "fem":
            return _fem_tip_displacement(self._time, forcing, gain, values, self._classes)
        stiffness_terms = [values.get(n, 0.0) for n in DELTA_E_NAMES]
        if any(stiffness_terms) and transducer in ("lumped", "lumped_nonlinear"):
            relative_stiffness = relative_stiffness_change(magnetization, values)
            return varying_stiffness_response(self._time, gain * forcing, relative_stiffness,
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
        return lti_response(self._time, forcing, A, B, C, start="steady", classes=self._classes)


def even_law_forcing(magnetization, Ms, M0, coefficients):
    """The magnetostriction law's even terms beyond M^2 (:data:`.effects.EVEN_LAW_POWERS`), in the gain's units
    times A/m: ``Ms*sum(zeta_n*(m^n - m0^n))`` over ``coefficients`` {name: zeta_n} with m = M/Ms, zero at the
    bias M0 as the law's other terms. Why even powers of M/Ms about M = 0, not of M - M0: the magnetostriction of a
    demagnetized rod is even in M (lambda(-M) = lambda(M), lambda(0) = 0), and its saturation is reached at
    |M| = Ms whatever the bias; the linear and (M - M0)^2 terms already hold a law about a bias."""
    m, m0 = magnetization / Ms, M0 / Ms
    return Ms * sum(value * (m ** EVEN_LAW_POWERS[name] - m0 ** EVEN_LAW_POWERS[name])
                    for name, value in coefficients.items())


def relative_stiffness_change(magnetization, values):
    """The Delta-E family's relative stiffness change khat(M)/khat - 1 (1) at ``magnetization`` (A/m):
    ``delta_e*(m^2 - m0^2) + delta_e_linear*(m - m0) + delta_e_cubic*(m^3 - m0^3) + delta_e_quartic*(m^4 - m0^4)``,
    m = M/Ms, zero at the bias M0."""
    m, m0 = magnetization / values["Ms"], values["M0"] / values["Ms"]
    change = values.get("delta_e", 0.0) * (m ** 2 - m0 ** 2) + values.get("delta_e_linear", 0.0) * (m - m0)
    cubic, quartic = values.get("delta_e_cubic", 0.0), values.get("delta_e_quartic", 0.0)
    if cubic:
        change = change + cubic * (m ** 3 - m0 ** 3)
    return change + quartic * (m ** 4 - m0 ** 4) if quartic else change


def gain_drift_factor(fraction, linear, settling_share, tau):
    """The ``sensor_gain_drift`` family: the sensor's gain relative to its gain at the record's start,
    ``1 + linear*f + settling_share*(1 - exp(-f/tau))`` at ``fraction`` f (the record's time mapped to [0, 1]; tau
    in record lengths).

    Why a settling term and not a polynomial in f: the held-out block is the record's end, so the family
    must extrapolate; a warm-up settles, where a quadratic fitted to the first 70 % turns back (it misses the
    end of a settling with tau = 0.3 records by ~19 % of its size, the settling term not at all). A linear
    creep is the member with settling = 0, a quadratic one the limit of a long tau."""
    return 1.0 + linear * fraction + settling_share * settling(fraction, tau)


def settling(fraction, tau):
    """``1 - exp(-f/tau)`` at ``fraction`` f (the record's time mapped to [0, 1]; tau in record lengths): a
    warm-up that settles, the drifts' basis beside their polynomial terms (:func:`gain_drift_factor`, the
    ``sensor_drift`` family)."""
    return -np.expm1(-fraction / tau)


#: Damping ratio of the input dynamics' pair of poles: a Butterworth pair (an amplifier's bandwidth). Why fixed:
#: with a free damping the fit could drive the pair toward no damping, where the field rings through the whole
#: record and the hysteresis simulation's field substeps multiply (a fit that ran for tens of minutes).
INPUT_POLE_DAMPING = 1.0 / np.sqrt(2.0)


def input_dynamics(time, field, tau, delay, tau2=0.0, classes=None):
    """The ``input_lag`` family: the field (A/m) in the material for the recorded ``field``, delayed by
    ``delay`` (s; the first sample held before the record starts), then lagged by ``tau`` (s),
    ``tau*H' = H_rec(t - delay) - H``, and filtered by a Butterworth pair of poles at 1/(2*pi*tau2) Hz
    (:data:`INPUT_POLE_DAMPING`; :func:`sensor_dynamics`), starting settled; tau2 = 0 is the first-order lag
    and the recorded field itself when all vanish."""
    if tau == 0.0 and delay == 0.0 and tau2 == 0.0:
        return field
    out = np.interp(time - delay, time, field) if delay > 0.0 else field
    out = sensor_dynamics(time, out, tau, 0.0, classes)
    if tau2 > 0.0:
        out = sensor_dynamics(time, out, 2.0 * INPUT_POLE_DAMPING * tau2, tau2, classes)
    return np.ascontiguousarray(out)


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


def sensor_dynamics(time, signal, tau, tau2=0.0, classes=None):
    """A second-order low-pass ``tau2^2*y'' + tau*y' + y = u`` (tau, tau2 in s), starting settled: a
    resonance at f_n = 1/(2*pi*tau2) Hz with damping ratio tau/(2*tau2) (a displacement probe or an
    amplifier that rings); tau2 = 0 is the first-order lag ``tau*y' = u - y``, and the signal itself
    when both vanish. Exact first-order-hold steps (:func:`~.kernels.lti_response`), so a resonance
    near the Nyquist frequency is stepped without a stiffness limit."""
    if tau2 > 0.0:
        inverse = 1.0 / tau2 ** 2
        return lti_response(time, signal, [[0.0, 1.0], [-inverse, -tau * inverse]], [0.0, inverse], [1.0, 0.0],
                            start="steady", classes=classes)
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
