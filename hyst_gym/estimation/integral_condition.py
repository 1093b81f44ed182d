"""Theorem 1's integral condition (22) and the excitation conditions 3.1(a)/(b) on recorded traces.

Theorem 1 (Nealis & Smith, §3.1): the scalar min-max estimator (14)-(16) converges if for
every ``t1`` there are ``T0``, ``eps0``, ``delta0`` and a subinterval
``[t2, t2 + delta0]`` of ``[t1, t1 + T0]`` with

    integral_{t2}^{t2+delta0} beta*nu*(f(u, thetahat(t2)) - f(u, a)) dtau  >=  2*eps + eps0*|theta_tilde(t2)|   (22)

where ``f(u, theta)`` is M (A/m) under the parameter ``theta`` for the whole field history
(the model bank), ``nu`` the plant gain of ``y' = -lambda*y + nu*M``, ``eps`` the dead zone
of (14) (units of y), ``theta_tilde = thetahat - a`` (A/m), and ``beta = +1`` where
``f(u, .)`` is convex at thetahat and ``-1`` where it is concave. The estimate inside the
integral is *frozen* at ``t2``; ``beta`` is taken pointwise, at the frozen estimate, at each
instant tau (the integrand of (22) as the field guide writes it). For ``nu = 1`` the
integral has units of A/m*s, which are the units of y, so both sides compare in y.

The persistent-excitation conditions read, over a stretch of time:

* 3.1(a): the input reverses the sign of the integrand of (22) while beta stays fixed;
* 3.1(b): the input reverses beta while "the sign of the integrand" stays fixed. The text
  leaves open whether that integrand includes beta; both readings are computed here:
  ``b_beta`` (the sign of ``beta*nu*(f(thetahat) - f(a))`` stays fixed, as
  :class:`~.pe.PEMonitor` reads it) and ``b_raw`` (the sign of ``nu*(f(thetahat) - f(a))``
  stays fixed: the reading under which the paper's Fig. 8 shows 3.1(b) on its ramp).

Everything here works on recorded traces with plain numpy: the bank's node values
``f(u(t_k), theta_i)`` (T, G) (:func:`bank_trace` replays a field trace through the
estimation layer's :class:`~.bank.ModelBank` to get them), the estimate thetahat(t_k) and,
for the truth-based tests, a(t_k). Values between nodes come from the bank's own C1 cubic
Hermite interpolant (finite-difference node slopes), the compiled kernel the estimator uses,
evaluated for a frozen estimate at every instant of a window in one call.

**Truth-free version.** An agent sees the bank but not a. :func:`truth_free_condition`
replaces ``f(u, a)`` by the edges of the bank's envelope of the candidates that lie at
least ``radius`` (A/m) from the frozen estimate: ``f(u, thetahat(t2) - radius)`` and
``f(u, thetahat(t2) + radius)`` (a side whose candidate falls outside Theta is dropped,
since a lies in Theta). A window passes when (22) holds, in some subinterval, for every
remaining side. When the candidate set collapses onto a single point a (one side left, at
distance |theta_tilde|) it is the truth-based test exactly. For an f monotone in theta the
two sides give integrands of opposite sign, so the truth-free test demands within T0
exactly what 3.1(a)/(b) ask for: a reversal of the integrand's sign or of beta.

Units: time and dt in s, theta in A/m, bank values in A/m, integrals in A/m*s (= units of y
for the paper's plant, nu = 1), eps in units of y, eps0 in units of y per A/m.
"""

from __future__ import annotations

import numpy as np

from .bank import ModelBank
from ._kernels import interpolate_rows
from .config import EstimatorConfig


# ---------------------------------------------------------------------------------------- bank values


def bank_trace(config: EstimatorConfig, field) -> np.ndarray:
    """Node values ``f(u(t_k), theta_i)`` (A/m), shape (T, G) or (E, T, G), of the estimation
    layer's bank driven from the demagnetized state at H = 0 through ``field`` (A/m, (T,) or (E, T)).

    This is the bank the estimator and the agent see (same grid, same ``max_field_step``)."""
    field = np.asarray(field, dtype=np.float64)
    single = field.ndim == 1
    field = np.atleast_2d(field)
    if field.ndim != 2 or field.shape[1] < 1 or not np.all(np.isfinite(field)):
        raise ValueError(f"bank_trace: field must be a finite (T,) or (E, T) array of A/m, got shape {field.shape}")
    systems, steps = field.shape
    bank = ModelBank(config, n_systems=systems)
    out = np.empty((systems, steps, config.grid_size))
    for k in range(steps):
        bank.advance(np.ascontiguousarray(field[:, k]))
        out[:, k] = bank.magnetization
    return out[0] if single else out


def interpolate(grid, values, theta, rows=None):
    """``(f, df/dtheta, d2f/dtheta2)`` of the bank's cubic Hermite interpolant at ``theta``: the
    estimation layer's own compiled interpolant (:func:`~._kernels.interpolate_rows`), so an
    estimate here gives the numbers the estimator sees.

    Parameters
    ----------
    grid : ndarray (G,)
        Increasing, equally spaced nodes, A/m.
    values : ndarray (R, G)
        Node values, one row per instant (A/m).
    theta : ndarray
        Where to evaluate, A/m (clamped to the end intervals like the bank).
    rows : ndarray of int, optional
        Row of ``values`` for each entry of ``theta`` (same shape); default ``arange(R)``
        (then ``theta`` has shape (R,)).

    Returns
    -------
    three arrays shaped like ``theta``: f (A/m), df/dtheta (dimensionless), d2f/dtheta2 (per A/m).
    """
    grid = np.ascontiguousarray(grid, dtype=np.float64)
    values = np.ascontiguousarray(values, dtype=np.float64)
    theta = np.asarray(theta, dtype=np.float64)
    if values.ndim != 2 or values.shape[1] != grid.size or grid.size < 3:
        raise ValueError(f"interpolate: values must be (R, {grid.size}) over a grid of >= 3 nodes, got "
                         f"{values.shape}")
    if rows is None:
        if theta.shape != (values.shape[0],):
            raise ValueError(f"interpolate: theta must be ({values.shape[0]},) without rows, got {theta.shape}")
        rows = np.arange(values.shape[0])
    rows = np.asarray(rows)
    if rows.shape != theta.shape:
        raise ValueError(f"interpolate: rows {rows.shape} and theta {theta.shape} must have one shape")
    if not np.all(np.isfinite(theta)):
        raise ValueError("interpolate: theta must be finite")
    flat_theta = np.ascontiguousarray(theta.ravel())
    out = [np.empty(flat_theta.size) for _ in range(3)]
    interpolate_rows(grid, values, np.ascontiguousarray(rows.ravel(), dtype=np.int64), flat_theta, *out)
    return tuple(o.reshape(theta.shape) for o in out)


def curvature_sign(curvature) -> np.ndarray:
    """beta of Theorem 1 from d2f/dtheta2: +1 where >= 0 (convex), -1 where < 0 (concave)."""
    return np.where(np.asarray(curvature) >= 0.0, 1.0, -1.0)


# ---------------------------------------------------------------------------------------- (22)


def _check_trace(grid, bank_values, theta_hat, dt, delta_steps):
    grid = np.asarray(grid, dtype=np.float64)
    bank_values = np.asarray(bank_values, dtype=np.float64)
    theta_hat = np.asarray(theta_hat, dtype=np.float64)
    if bank_values.ndim != 2 or bank_values.shape[1] != grid.size:
        raise ValueError(f"integral condition: bank_values must be (T, {grid.size}), got {bank_values.shape}")
    steps = bank_values.shape[0]
    if theta_hat.shape != (steps,) or not np.all(np.isfinite(theta_hat)):
        raise ValueError(f"integral condition: theta_hat must be finite with shape ({steps},), got {theta_hat.shape}")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"integral condition: dt must be a finite number > 0 s, got {dt!r}")
    if isinstance(delta_steps, bool) or not isinstance(delta_steps, (int, np.integer)) or delta_steps < 1:
        raise ValueError(f"integral condition: delta_steps must be an integer >= 1, got {delta_steps!r}")
    if delta_steps >= steps:
        raise ValueError(f"integral condition: delta_steps = {delta_steps} needs more than {steps} samples")
    return grid, bank_values, theta_hat


def frozen_estimate(grid, bank_values, theta_hat, delta_steps: int):
    """The part of :func:`frozen_integrals` that does not depend on a: for every subinterval
    start s, ``f(u(t_k), thetahat(t_s))`` and beta at ``thetahat(t_s)`` over ``k = s..s+delta_steps``.

    Returns ``(rows, f_hat, beta)``: sample indices (S, W+1), A/m (S, W+1) and +-1 (S, W+1);
    pass it as ``frozen=`` to save the work on repeated calls."""
    grid, bank_values, theta_hat = _check_trace(grid, bank_values, theta_hat, 1.0, delta_steps)
    starts = bank_values.shape[0] - delta_steps
    rows = np.arange(starts)[:, None] + np.arange(delta_steps + 1)[None, :]  # (S, W+1)
    frozen = np.broadcast_to(theta_hat[:starts, None], rows.shape)
    f_hat, _, curvature = interpolate(grid, bank_values, frozen, rows)
    return rows, f_hat, curvature_sign(curvature)


def frozen_integrals(grid, bank_values, theta_hat, reference, dt: float, delta_steps: int, gain: float = 1.0,
                     reference_values=None, frozen=None):
    """The integral of (22) over every subinterval ``[t_s, t_s + delta_steps*dt]`` of a trace.

    Parameters
    ----------
    grid : ndarray (G,)
        The bank's nodes over Theta, A/m.
    bank_values : ndarray (T, G)
        ``f(u(t_k), theta_i)``, A/m, at the samples ``t_k = t_0 + k*dt``.
    theta_hat : ndarray (T,)
        The estimate at each sample, A/m; frozen at the start ``t_s`` of each subinterval.
    reference : ndarray (T,) or (S,) with ``S = T - delta_steps``, or a list of them
        The parameter in ``f(u, a)``, A/m: shape (T,) is a per-instant truth a(t_k);
        shape (S,) is one value per subinterval start, held over it (the truth-free candidates).
        A list gives one result per entry (the frozen estimate's values are computed once).
    dt : float
        Sample spacing, s.
    delta_steps : int
        delta0 of (22) in samples; each integral uses ``delta_steps + 1`` samples (trapezoid rule).
    gain : float
        nu of the plant ``y' = -lambda*y + nu*M``.
    reference_values : ndarray (T,), optional
        ``f(u, a)`` itself at each sample (A/m), in place of the bank's value at ``reference``
        (which then only sets ``error``): e.g. the plant's own M when a drifts, since a
        material whose a changed along the way is not the bank's model at the final a.
    frozen : tuple, optional
        :func:`frozen_estimate` of the same trace and ``delta_steps``.

    Returns
    -------
    dict (a list of dicts for a list of references) of (S,) arrays: ``with_beta`` (the integral
    of ``beta*nu*(f(thetahat(t_s)) - f(a))``, A/m*s), ``without_beta`` (the same without beta),
    ``error`` (``|thetahat(t_s) - a(t_s)|``, A/m).
    """
    grid, bank_values, theta_hat = _check_trace(grid, bank_values, theta_hat, dt, delta_steps)
    steps = bank_values.shape[0]
    starts = steps - delta_steps
    several = isinstance(reference, (list, tuple))
    references = [np.asarray(r, dtype=np.float64) for r in (reference if several else [reference])]
    for ref in references:
        if ref.shape not in ((steps,), (starts,)) or not np.all(np.isfinite(ref)):
            raise ValueError(f"frozen_integrals: reference must be finite with shape ({steps},) or ({starts},), "
                             f"got {ref.shape}")
    if frozen is None:
        frozen = frozen_estimate(grid, bank_values, theta_hat, delta_steps)
    rows, f_hat, beta = frozen
    if rows.shape != (starts, delta_steps + 1):
        raise ValueError("frozen_integrals: frozen was computed for another trace or delta_steps")
    weights = np.full(delta_steps + 1, dt)
    weights[[0, -1]] = 0.5 * dt  # trapezoid rule
    out = []
    if reference_values is not None:
        reference_values = np.asarray(reference_values, dtype=np.float64)
        if several or references[0].shape != (steps,) or reference_values.shape != (steps,) \
                or not np.all(np.isfinite(reference_values)):
            raise ValueError(f"frozen_integrals: reference_values must be finite with shape ({steps},), with one "
                             f"per-instant reference")
    for ref in references:
        if reference_values is not None:
            f_ref = reference_values[rows]
            start_reference = ref[:starts]
        elif ref.shape == (steps,):
            f_ref = interpolate(grid, bank_values, ref)[0][rows]
            start_reference = ref[:starts]
        else:
            f_ref = interpolate(grid, bank_values, np.broadcast_to(ref[:, None], rows.shape), rows)[0]
            start_reference = ref
        raw = gain * (f_hat - f_ref)
        out.append({"with_beta": (beta * raw) @ weights, "without_beta": raw @ weights,
                    "error": np.abs(theta_hat[:starts] - start_reference)})
    return out if several else out[0]


def margin(integral, error, eps: float, eps0: float) -> np.ndarray:
    """Left side minus right side of (22): ``integral - (2*eps + eps0*error)`` (units of y)."""
    if not (np.isfinite(eps) and eps >= 0 and np.isfinite(eps0) and eps0 >= 0):
        raise ValueError(f"margin: eps and eps0 must be finite numbers >= 0, got {eps!r}, {eps0!r}")
    return np.asarray(integral, dtype=np.float64) - (2.0 * eps + eps0 * np.asarray(error, dtype=np.float64))


def exists_in_window(values, span: int) -> np.ndarray:
    """``max(values[t1 : t1 + span + 1])`` for every ``t1`` with a full window: shape (S - span,).

    With ``values`` the (22) margin per subinterval start and ``span = (T0 - delta0)/dt``,
    entry ``t1`` is >= 0 exactly when some subinterval of ``[t1, t1 + T0]`` meets (22)."""
    values = np.asarray(values, dtype=np.float64)
    if isinstance(span, bool) or not isinstance(span, (int, np.integer)) or span < 0:
        raise ValueError(f"exists_in_window: span must be an integer >= 0, got {span!r}")
    if values.ndim != 1 or values.size <= span:
        raise ValueError(f"exists_in_window: need a 1-D array longer than span = {span}, got {values.shape}")
    return np.lib.stride_tricks.sliding_window_view(values, span + 1).max(axis=1)


def integral_condition(grid, bank_values, theta_hat, a_true, dt: float, delta_steps: int, span: int, eps: float,
                       eps0: float, gain: float = 1.0, reference_values=None) -> dict:
    """Theorem 1's condition (22) with the truth, over moving windows ``[t1, t1 + T0]``.

    ``T0 = (delta_steps + span)*dt`` s; ``a_true`` (T,) or scalar, A/m; the other arguments as in
    :func:`frozen_integrals` and :func:`margin`. Returns (W,) arrays over window starts ``t1``
    (``W = T - delta_steps - span``): ``beta`` / ``no_beta`` (the best margin of (22) in the
    window with and without beta, units of y; >= 0 means the window meets (22)),
    ``magnitude`` (the same for ``|integral|``: the sign requirement dropped) and ``error``
    (``|theta_tilde(t1)|``, A/m). ``reference_values``: as in :func:`frozen_integrals`.
    """
    steps = np.asarray(bank_values).shape[0]
    a_true = np.broadcast_to(np.asarray(a_true, dtype=np.float64), (steps,))
    parts = frozen_integrals(grid, bank_values, theta_hat, a_true, dt, delta_steps, gain, reference_values)
    out = {name: exists_in_window(margin(parts[key], parts["error"], eps, eps0), span)
           for name, key in (("beta", "with_beta"), ("no_beta", "without_beta"))}
    out["magnitude"] = exists_in_window(margin(np.abs(parts["without_beta"]), parts["error"], eps, eps0), span)
    out["error"] = parts["error"][:out["beta"].size]
    return out


def candidate_margins(grid, bank_values, theta_hat, radius, dt: float, delta_steps: int, eps: float, eps0: float,
                      gain: float = 1.0, with_beta: bool = True, frozen=None):
    """(22) margins (units of y) per subinterval start for the two envelope candidates
    ``thetahat(t2) -/+ radius`` (A/m, scalar or (S,)); a candidate outside Theta gets ``nan``.

    Returns ``(below, above)``, each (S,), for :func:`truth_free_condition`; ``frozen`` as in
    :func:`frozen_integrals`."""
    grid, bank_values, theta_hat = _check_trace(grid, bank_values, theta_hat, dt, delta_steps)
    starts = bank_values.shape[0] - delta_steps
    radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), (starts,))
    if not np.all(np.isfinite(radius) & (radius > 0)):
        raise ValueError("candidate_margins: radius must be finite and > 0 A/m")
    estimate = theta_hat[:starts]
    candidates = [estimate - radius, estimate + radius]
    parts = frozen_integrals(grid, bank_values, theta_hat, [np.clip(c, grid[0], grid[-1]) for c in candidates], dt,
                             delta_steps, gain, frozen=frozen)
    key = "with_beta" if with_beta else "without_beta"
    return tuple(np.where((c >= grid[0]) & (c <= grid[-1]), margin(p[key], radius, eps, eps0), np.nan)
                 for c, p in zip(candidates, parts))


def truth_free_condition(grid, bank_values, theta_hat, radius, dt: float, delta_steps: int, span: int,
                         eps: float, eps0: float, gain: float = 1.0, side=None, with_beta: bool = True,
                         margins=None) -> np.ndarray:
    """(22) with the bank's envelope in place of the truth (module docstring), per window start.

    Parameters
    ----------
    radius : float or ndarray (S,)
        Distance (A/m, > 0) of the candidates ``thetahat(t2) -/+ radius`` from the frozen
        estimate, one value or one per subinterval start (``S = T - delta_steps``).
    side : ndarray (S,) of -1, 0, +1, optional
        Default (None): both candidates, each with its own subinterval: the window passes when
        for *every* candidate some subinterval meets (22) (a certificate wherever a lies).
        Given: the candidates kept at each start t2 (-1 only the one below thetahat, +1 only
        the one above, 0 both), and a subinterval passes when (22) holds for every candidate
        kept there. An agent can tell the side from the sign of its tuning error
        (``sign(ytilde) = sign(f(thetahat) - f(a))`` outside the dead zone) and the bank's slope.
    margins : (below, above), optional
        :func:`candidate_margins` already computed with the same arguments (saves the work).
    others
        As in :func:`integral_condition`; ``with_beta=False`` drops beta from the integrand.

    Returns
    -------
    ndarray (W,)
        Per window start t1: the smallest, over the kept candidates, of the best (22) margin
        in ``[t1, t1 + T0]`` (units of y; >= 0: the window meets (22) wherever among the kept
        candidates a lies). A candidate outside Theta = [grid[0], grid[-1]] cannot be a and is
        dropped; ``+inf`` where none is kept.
    """
    if margins is None:
        margins = candidate_margins(grid, bank_values, theta_hat, radius, dt, delta_steps, eps, eps0, gain, with_beta)
    starts = margins[0].size
    per_start = side is not None
    side = np.zeros(starts) if side is None else np.asarray(side, dtype=np.float64)
    if side.shape != (starts,) or not np.all(np.isin(side, (-1.0, 0.0, 1.0))):
        raise ValueError(f"truth_free_condition: side must be ({starts},) of -1, 0, +1")
    if isinstance(span, bool) or not isinstance(span, (int, np.integer)) or not 0 <= span < starts:
        raise ValueError(f"truth_free_condition: span must be an integer in [0, {starts}), got {span!r}")
    worst = np.full(starts - span, np.inf)
    worst_start = np.full(starts, np.inf)
    for sign, values in zip((-1.0, 1.0), margins):
        kept = np.isfinite(values) & ((side == 0) | (side == sign))
        side_margin = np.where(kept, values, np.inf)
        if per_start:
            worst_start = np.minimum(worst_start, side_margin)
        else:
            worst = np.minimum(worst, exists_in_window(side_margin, span))
    if per_start:
        worst = exists_in_window(worst_start, span)
    return worst


def required_eps0(initial_error: float, band: float, horizon_s: float, delta_s: float, decay_rate: float,
                  gamma: float, gain: float = 1.0) -> float:
    """eps0 of (22) sized so that meeting (22) in every window settles the estimate in time.

    Near the truth the scalar estimator reduces to the comparison system of
    :mod:`~.convergence`, ``e' = -gamma*nu*phi*ytilde``, ``ytilde' = -lambda*ytilde + nu*phi*e``
    with ``phi = df/da``. While it is overdamped, ``ytilde`` follows ``nu*phi*e/lambda`` and
    ``e`` decays at the rate ``gamma*nu**2*phi**2/lambda`` (1/s). Going from ``initial_error``
    to ``band`` (A/m) within ``horizon_s`` (s) needs ``phi >= phi_req =
    sqrt(lambda*ln(initial_error/band)/(gamma*nu**2*horizon_s))``. Linearized, the integral of
    (22) over ``delta_s`` is ``nu*phi*delta_s*|theta_tilde|`` (when beta has the right sign),
    so (22) with ``eps0 = nu*delta_s*phi_req`` asks each window for that sensitivity.
    Returns eps0 in units of y per A/m (s for the paper's plant); 0 if ``initial_error <= band``.
    """
    for name, value in (("band", band), ("horizon_s", horizon_s), ("delta_s", delta_s),
                        ("decay_rate", decay_rate), ("gamma", gamma), ("gain", gain)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"required_eps0: {name} must be a finite number > 0, got {value!r}")
    if not (np.isfinite(initial_error) and initial_error >= 0):
        raise ValueError(f"required_eps0: initial_error must be a finite number >= 0 A/m, got {initial_error!r}")
    if initial_error <= band:
        return 0.0
    phi = np.sqrt(decay_rate * np.log(initial_error / band) / (gamma * gain ** 2 * horizon_s))
    return float(gain * delta_s * phi)


# ---------------------------------------------------------------------------------------- 3.1(a)/(b)


def sign_conditions(integrand, beta, window: int, tolerance: float = 0.0) -> dict:
    """Windowed 3.1(a) and both readings of 3.1(b) on a per-step trace.

    Parameters
    ----------
    integrand : ndarray (T,)
        ``nu*(f(u, thetahat) - f(u, a))`` at each step, *without* beta (units of nu*M).
    beta : ndarray (T,)
        +1/-1 at each step.
    window : int
        Window length in steps (>= 2).
    tolerance : float
        Values with ``|integrand| <= tolerance`` carry no sign (they neither reverse nor keep it).

    Returns
    -------
    dict of boolean (T - window + 1,) arrays, one per window ``[k, k + window)``:
    ``a`` (the sign of beta*integrand reverses, beta fixed), ``b_beta`` (beta reverses, the sign
    of beta*integrand fixed) and ``b_raw`` (beta reverses, the sign of the integrand fixed).
    A window whose integrand has no sign at all meets none of them.
    """
    integrand = np.asarray(integrand, dtype=np.float64)
    beta = np.where(np.asarray(beta, dtype=np.float64) >= 0.0, 1.0, -1.0)
    if integrand.ndim != 1 or beta.shape != integrand.shape:
        raise ValueError(f"sign_conditions: integrand and beta must be 1-D of one length, got "
                         f"{integrand.shape} and {beta.shape}")
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or not 2 <= window <= integrand.size:
        raise ValueError(f"sign_conditions: window must be an integer in [2, {integrand.size}], got {window!r}")
    signed = np.where(np.abs(integrand) > tolerance, np.sign(integrand), 0.0)

    def both(x):  # does the window hold both +1 and -1?
        view = np.lib.stride_tricks.sliding_window_view(x, window)
        return (view > 0).any(axis=1) & (view < 0).any(axis=1)

    def one(x):  # does the window hold a sign, and only one?
        view = np.lib.stride_tricks.sliding_window_view(x, window)
        return (view != 0).any(axis=1) & ~both(x)

    beta_reverses = both(beta)
    return {"a": both(beta * signed) & ~beta_reverses,
            "b_beta": beta_reverses & one(beta * signed),
            "b_raw": beta_reverses & one(signed)}


# ---------------------------------------------------------------------------------------- ROC


def roc_auc(scores, labels) -> float:
    """Area under the ROC curve of ``scores`` for the binary ``labels`` (True = positive).

    The Mann-Whitney statistic with mid-ranks: P(score of a positive > score of a negative)
    + 0.5*P(tie). ``nan`` when one class is empty."""
    scores = np.asarray(scores, dtype=np.float64)
    labels = np.asarray(labels, dtype=bool)
    if scores.shape != labels.shape or scores.ndim != 1:
        raise ValueError(f"roc_auc: scores and labels must be 1-D of one length, got {scores.shape}, {labels.shape}")
    if not np.all(np.isfinite(scores)):
        raise ValueError("roc_auc: scores must be finite")
    positives = int(labels.sum())
    negatives = labels.size - positives
    if positives == 0 or negatives == 0:
        return float("nan")
    order = np.argsort(scores, kind="mergesort")
    ranks = np.empty(scores.size)
    sorted_scores = scores[order]
    # mid-ranks of tied groups
    edges = np.flatnonzero(np.diff(sorted_scores)) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [scores.size]])
    ranks[order] = np.repeat((starts + ends + 1) / 2.0, ends - starts)
    return float((ranks[labels].sum() - positives * (positives + 1) / 2.0) / (positives * negatives))


def roc_curve(scores, labels):
    """``(false_positive_rate, true_positive_rate)`` over all thresholds, from (0, 0) to (1, 1)."""
    scores = np.asarray(scores, dtype=np.float64)
    labels = np.asarray(labels, dtype=bool)
    thresholds = np.unique(scores)[::-1]
    positives, negatives = max(int(labels.sum()), 1), max(int((~labels).sum()), 1)
    tpr = [0.0] + [float(np.sum(labels & (scores >= t))) / positives for t in thresholds]
    fpr = [0.0] + [float(np.sum(~labels & (scores >= t))) / negatives for t in thresholds]
    return np.array(fpr), np.array(tpr)


def bootstrap_auc(scores, labels, clusters, n_boot: int = 2000, seed: int = 0, level: float = 0.95):
    """Percentile bootstrap CI of :func:`roc_auc`, resampling whole clusters with replacement.

    ``clusters`` (one id per episode, e.g. the agent run that played it): episodes of one
    input are not independent, so the input, not the episode, is the unit resampled.
    Resamples with one class missing are drawn again. Returns ``(lo, hi)``.
    """
    scores = np.asarray(scores, dtype=np.float64)
    labels = np.asarray(labels, dtype=bool)
    clusters = np.asarray(clusters)
    if clusters.shape != scores.shape:
        raise ValueError(f"bootstrap_auc: clusters {clusters.shape} must match scores {scores.shape}")
    if isinstance(n_boot, bool) or not isinstance(n_boot, (int, np.integer)) or n_boot < 1:
        raise ValueError(f"bootstrap_auc: n_boot must be an integer >= 1, got {n_boot!r}")
    if not 0 < level < 1:
        raise ValueError(f"bootstrap_auc: level must lie in (0, 1), got {level!r}")
    ids, index = np.unique(clusters, return_inverse=True)
    members = [np.flatnonzero(index == i) for i in range(ids.size)]
    rng = np.random.default_rng(seed)
    values = []
    attempts = 0
    while len(values) < n_boot and attempts < 20 * n_boot:
        attempts += 1
        pick = np.concatenate([members[i] for i in rng.integers(0, ids.size, ids.size)])
        if labels[pick].all() or not labels[pick].any():
            continue
        values.append(roc_auc(scores[pick], labels[pick]))
    if not values:
        return float("nan"), float("nan")
    tail = 100 * (1 - level) / 2
    lo, hi = np.percentile(values, [tail, 100 - tail])
    return float(lo), float(hi)


__all__ = ["bank_trace", "interpolate", "curvature_sign", "frozen_estimate", "frozen_integrals",
           "margin",
           "exists_in_window", "integral_condition", "required_eps0", "candidate_margins",
           "truth_free_condition", "sign_conditions", "roc_auc",
           "roc_curve", "bootstrap_auc"]
