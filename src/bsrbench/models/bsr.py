"""``BayesianSR``: the paper's Bayesian sparse-representation regressor (PM in its tables).

Babagholami-Mohamadabadi, Jourabloo, Zarghami & Kasaei, "A Bayesian Framework for Sparse Representation-Based
3D Human Pose Estimation", IEEE Signal Processing Letters 21(3), 2014. Inputs ``x_i`` and outputs ``y_i`` are
coded by two dictionaries ``D^x``, ``D^y`` with shared sparse codes ``alpha_i = b_i * s_i``; the code
activation logits ``w_k`` have a Gaussian-process prior over the training outputs, so points with similar
outputs use similar atoms. Posterior inference is Gibbs sampling with the corrected conditionals of
docs/model.md (kernels in :mod:`bsrbench.models._bsr_kernels`); prediction averages, over
retained posterior samples, ``D^y alpha_t`` where ``alpha_t`` is drawn given ``x_t`` and the logits of
``x_t``'s nearest training inputs (paper, Section "Pose Prediction").
"""

import logging
import time
from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils import check_random_state
from sklearn.utils._param_validation import (
    Interval,
    InvalidParameterError,
    StrOptions,
    validate_parameter_constraints,
)
from sklearn.utils.validation import check_is_fitted, validate_data

from ..errors import InputError, SamplerError
from ..metrics import mean_angle_error
from . import _bsr_kernels as kern
from .scaling import (
    INPUT_SCALINGS,
    InputScaler,
    check_finite_input,
    clip_to_bounds,
    output_bounds,
)

__all__ = ["BayesianSR"]

logger = logging.getLogger("bsrbench.models.bsr")

_LOG_EVERY = 100
_CHUNK = 1024  # test points per prediction call (bounds the (points, samples, outputs) draw array)


PREDICTIONS = ("conditional", "paper-text")
LOGIT_KERNELS = kern.LOGIT_KERNELS


class _Choices(StrOptions):
    """StrOptions whose error message lists the choices sorted (a set's order varies between runs)."""

    def __str__(self):
        return f"a str among {sorted(self.options)}"


class _Range(Interval):
    """An Interval that refuses booleans (True would pass as the number 1)."""

    def is_satisfied_by(self, val):
        return not isinstance(val, (bool, np.bool_)) and super().is_satisfied_by(val)


def _count(low, high=None):
    return _Range(Integral, low, high, closed="left" if high is None else "both")


def _positive():
    return _Range(Real, 0, np.inf, closed="neither")


def _validate(constraints, params, caller):
    """scikit-learn's parameter validation, its error raised as InputError (names parameter, value, choices)."""
    try:
        validate_parameter_constraints(constraints, params, caller_name=caller)
    except InvalidParameterError as exc:
        raise InputError(str(exc)) from None


class BayesianSR(RegressorMixin, BaseEstimator):
    """Bayesian sparse representation with coupled dictionaries and a pose-kernel logit prior.

    Parameters
    ----------
    n_atoms : int, default=128
        Number of dictionary atoms K.
    n_neighbors : int, default=5
        Number j of nearest training inputs whose logits are averaged for a test point. Can be overridden
        in :meth:`predict`, so one fit serves every j in a cross-validation.
    n_iter : int, default=1200
        Gibbs sweeps in total (the paper: 1200).
    n_burn_in : int, default=700
        Sweeps discarded before samples are retained (the paper: 700). Must be < ``n_iter``.
    thin : int, default=10
        Keep every ``thin``-th sweep after burn-in for prediction (1200/700/10 keeps 50 samples). Must be
        <= ``n_iter - n_burn_in`` (at least one retained sample).
    w_update : {"ess", "mh", "paper-printed-ratio", "paper-literal"}, default="ess"
        Update of the logits: elliptical slice sampling (Murray, Adams & MacKay 2010), the bound-based
        Metropolis-Hastings proposal of the paper (Appendix A) with the correct acceptance ratio, or two
        ablations with the wrong target: "paper-printed-ratio" keeps the tight bound lambda = sigmoid(-z w) and
        uses the paper's printed (independence-chain) ratio; "paper-literal" uses lambda = sigmoid(+z w) and the
        printed ratio, exactly as the appendix prints them. Both exact updates pass the Geweke test and both
        ablations fail it (tests/test_bsr_geweke.py). ESS is the default because it mixes far better: the MH
        proposal ``N(Sigma Lambda(w), Sigma)`` is a global move whose acceptance collapses with N (about 0.3%
        at N = 100 on the authors' features, against the paper's reported > 94%), while ESS always moves at a
        similar cost per sweep.
    atom_update : {"block", "single"}, default="block"
        Update of the dictionaries: all atoms jointly from their K x K posterior precision (exact, mixes
        better per sweep when atoms are correlated) or one atom at a time as in the paper's Gibbs scheme
        (cheaper per sweep at large K: O(N K M) against O(K^2 (N + M) + K^3)).
    n_predict_sweeps : int, default=10
        Gibbs sweeps of a test point's codes per posterior sample (from zero codes).
    n_predict_samples : int or None, default=None
        Number of retained posterior samples the prediction averages over: the last ``n_predict_samples``
        retained sweeps; None: all of them (the paper). 1 predicts from a single posterior draw of the
        dictionaries, codes and logits (those of the last sweep): a point estimate, without posterior
        averaging. Acts at prediction time (``set_params`` on a fitted model needs no refit).
    prediction : {"conditional", "paper-text"}, default="conditional"
        How a test point's codes are drawn per posterior sample. "conditional": (b_t, s_t) given x_t and the
        averaged logits w_t of its j nearest training inputs, by ``n_predict_sweeps`` Gibbs sweeps of the block
        update on the feature rows (docs/model.md, section "Prediction"). "paper-text": as the paper's
        Section "Pose Prediction" says, z_t ~ P(z_t | w_t) from the logits alone (not conditioned on x_t), then
        s_t | x_t, z_t exactly from its Gaussian (an ablation; combine with ``prediction_weighting``;
        ``n_predict_sweeps`` is not used).
    prediction_weighting : {"uniform", "likelihood"}, default="uniform"
        Average posterior samples uniformly, or with the paper's self-normalized weights
        ``beta_l = N(x_t; D^x alpha_t, 1/g_xy I)`` (g_nx with separate noise precisions).
    a0, b0 : float, default=1e-6
        Gamma(shape a0, rate b0) hyper-prior of the precisions g_s, g_x, g_y, and of g_xy unless ``a_xy``,
        ``b_xy`` are given (the paper: 1e-6 for all).
    a_xy, b_xy : float or None, default=None
        Gamma(shape, rate) prior of the noise precision g_xy alone (of g_nx and g_ny with ``noise="separate"``);
        None means a0 (resp. b0). A proper prior, e.g. a_xy = b_xy = 1, bounds the upward drift of g_xy when the
        codes can interpolate the training pairs (docs/pm-convergence.md).
    w_prior_mean : float, default=0.0
        Prior mean m of every logit, w_k ~ N(m 1, Sigma_w) (the paper: 0). A negative m makes P(on) small a priori
        (sparsity-inducing).
    logit_kernel : {"pose", "input", "identity"}, default="pose"
        Prior covariance Sigma_w of the logits w_k ~ N(m 1, Sigma_w) over the training points. "pose": the
        paper's ``exp(-||y_i - y_j|| / eta)`` on the standardized training poses (points with similar poses use
        similar atoms); "input": the same kernel on the scaled training inputs X (codes tied by appearance, not
        pose); "identity": Sigma_w = I, independent logits (no pose information). The sampler is exact for each
        (tests/test_bsr_mechanisms.py).
    eta_scale : float, default=1.0
        Factor on the paper's bandwidth ``eta = 2 sum_{i<j} ||y_i - y_j||^2 / (N (N - 1))`` of the "pose" or
        "input" kernel: < 1 makes Sigma_w nearer the identity, > 1 nearer a constant (all logits of an atom
        alike). Must be 1 with "identity".
    noise : {"shared", "separate"}, default="shared"
        One noise precision g_xy for the feature and output rows (the paper), or a model extension with g_nx for
        the Mx feature rows and g_ny for the My output rows, each with the (a_xy, b_xy) prior.
    standardize : bool, default=True
        Scale X with ``input_scaling`` and standardize Y per column with training statistics (predictions
        are mapped back); False: the raw X and Y.
    input_scaling : {"pooled", "bin", "none"}, default="pooled"
        Scaling of X (:class:`bsrbench.models.scaling.InputScaler`): each feature centred and all divided by
        one pooled scale, chosen by blocked 5-fold CV on training frames (:mod:`bsrbench.models.scaling`:
        5.19 deg at N = 30 against 6.04 for floored per-bin scaling and 6.62 for raw counts; why an
        unfloored per-feature scale fails off the training range: docs/scaling.md).
    random_state : int, RandomState instance or None, default=None
        Seed of the sampler (and of the per-test-point prediction streams).
    verbose : bool, default=False
        Log progress every 100 sweeps at INFO level (logger ``bsrbench.models.bsr``); DEBUG otherwise.

    Attributes
    ----------
    n_features_in_ : int
    n_outputs_ : int
    trace_ : dict of ndarray, one value per sweep
        ``log_likelihood``, ``g_xy``, ``g_s``, ``g_x``, ``g_y``, ``active_atoms`` (atoms used by any training
        point), ``acceptance`` (fraction of logit vectors that moved: the MH acceptance rate; for ESS the fraction
        whose slice move changed them, 1 unless the shrinkage degenerated). With ``noise="separate"`` also
        ``g_nx`` and ``g_ny``, and ``g_xy`` is then their pooled precision ``M / (Mx / g_nx + My / g_ny)`` (the
        inverse of the mean noise variance over all M rows, comparable with the shared g_xy).
    samples_ : dict of ndarray
        Retained posterior samples: ``Dx`` (L, K, Mx), ``Dy`` (L, K, My), ``W`` (L, N, K), ``g_s``, ``g_xy``,
        ``g_nx``, ``g_ny`` (L,), in standardized units.
    eta_ : float or None
        Bandwidth of the logit prior kernel ``exp(-||u_i - u_j|| / eta)`` (u: the standardized poses, or the
        scaled inputs with ``logit_kernel="input"``), eta_scale included; None with ``logit_kernel="identity"``.
    sigma_jitter_ : float
        Jitter added to the diagonal of Sigma_w for its Cholesky factor (0 if none was needed).
    fit_seconds_ : float
    """

    #: The column of the paper's Tables I-II that this class reproduces (:mod:`bsrbench.methods`).
    paper_name = "PM"

    _predict_time_params = ("n_neighbors",)

    _parameter_constraints = {
        "n_atoms": [_count(1)],
        "n_neighbors": [_count(1)],
        "n_iter": [_count(1)],
        "n_burn_in": [_count(0)],
        "thin": [_count(1)],
        "w_update": [_Choices(set(kern.W_UPDATES))],
        "atom_update": [_Choices(set(kern.ATOM_UPDATES))],
        "n_predict_sweeps": [_count(1)],
        "n_predict_samples": [_count(1), None],
        "prediction": [_Choices(set(PREDICTIONS))],
        "prediction_weighting": [_Choices({"uniform", "likelihood"})],
        "a0": [_positive()],
        "b0": [_positive()],
        "a_xy": [_positive(), None],
        "b_xy": [_positive(), None],
        "w_prior_mean": [_Range(Real, -np.inf, np.inf, closed="neither")],
        "logit_kernel": [_Choices(set(LOGIT_KERNELS))],
        "eta_scale": [_positive()],
        "noise": [_Choices(set(kern.NOISE_MODELS))],
        "standardize": ["boolean"],
        "input_scaling": [_Choices(set(INPUT_SCALINGS))],
        "random_state": ["random_state"],
        "verbose": ["verbose"],
    }

    def __init__(
        self,
        n_atoms=128,
        n_neighbors=5,
        n_iter=1200,
        n_burn_in=700,
        thin=10,
        w_update="ess",
        atom_update="block",
        n_predict_sweeps=10,
        n_predict_samples=None,
        prediction="conditional",
        prediction_weighting="uniform",
        a0=1e-6,
        b0=1e-6,
        a_xy=None,
        b_xy=None,
        w_prior_mean=0.0,
        logit_kernel="pose",
        eta_scale=1.0,
        noise="shared",
        standardize=True,
        input_scaling="pooled",
        random_state=None,
        verbose=False,
    ):
        self.n_atoms = n_atoms
        self.n_neighbors = n_neighbors
        self.n_iter = n_iter
        self.n_burn_in = n_burn_in
        self.thin = thin
        self.w_update = w_update
        self.atom_update = atom_update
        self.n_predict_sweeps = n_predict_sweeps
        self.n_predict_samples = n_predict_samples
        self.prediction = prediction
        self.prediction_weighting = prediction_weighting
        self.a0 = a0
        self.b0 = b0
        self.a_xy = a_xy
        self.b_xy = b_xy
        self.w_prior_mean = w_prior_mean
        self.logit_kernel = logit_kernel
        self.eta_scale = eta_scale
        self.noise = noise
        self.standardize = standardize
        self.input_scaling = input_scaling
        self.random_state = random_state
        self.verbose = verbose

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True
        tags.target_tags.single_output = True
        return tags

    # ------------------------------------------------------------------------------------------------------
    def _check_params(self, n_samples=None):
        """Validate the hyper-parameters (and, given ``n_samples``, that N training rows suffice for them).

        scikit-learn's ``_parameter_constraints`` first (types, ranges, allowed strings), then the checks that
        tie parameters together. Called by :meth:`fit` and, before any job runs, by the study's configuration
        check (:func:`bsrbench.config.check_method_settings`). Raises InputError naming the parameter, its value
        and what was expected.
        """
        try:
            self._validate_params()
        except InvalidParameterError as exc:
            raise InputError(str(exc)) from None
        n_iter, n_burn_in, thin = self.n_iter, self.n_burn_in, self.thin
        if n_burn_in >= n_iter:
            raise InputError(
                f"n_burn_in must be smaller than n_iter={n_iter} (some sweeps must be retained); "
                f"got n_burn_in={n_burn_in!r}"
            )
        if thin > n_iter - n_burn_in:
            raise InputError(
                f"thin={thin!r} retains no sweep of the n_iter - n_burn_in = {n_iter - n_burn_in} after "
                f"burn-in; expected thin <= {n_iter - n_burn_in} (every thin-th sweep after burn-in is kept)"
            )
        n_keep = (n_iter - n_burn_in) // thin
        if self.n_predict_samples is not None and self.n_predict_samples > n_keep:
            raise InputError(
                f"n_predict_samples={self.n_predict_samples!r} exceeds the {n_keep} retained samples "
                f"((n_iter - n_burn_in) // thin = ({n_iter} - {n_burn_in}) // {thin}); expected an integer in "
                f"[1, {n_keep}] or None (all)"
            )
        if self.logit_kernel == "identity" and self.eta_scale != 1.0:
            raise InputError(
                f"eta_scale={self.eta_scale!r} has no effect with logit_kernel='identity' (Sigma_w = I has no "
                f"bandwidth); expected eta_scale=1.0, or logit_kernel 'pose' or 'input'"
            )
        if n_samples is not None:
            self._check_n_samples(n_samples)

    def _check_n_samples(self, N):
        if N < self.n_neighbors or N < 2:
            raise InputError(
                f"BayesianSR needs at least max(2, n_neighbors={self.n_neighbors}) training rows; "
                f"got n_samples = {N}"
            )

    def fit(self, X, Y):
        """Run the Gibbs sampler on training inputs X (N, Mx) and outputs Y (N, My) or (N,)."""
        self._check_params()
        nx, ny = getattr(X, "shape", None), getattr(Y, "shape", None)
        if nx and ny and len(nx) >= 1 and len(ny) >= 1 and nx[0] != ny[0]:
            raise InputError(
                f"X and Y must have the same number of rows; got X with {nx[0]} and Y with {ny[0]}"
            )
        check_finite_input(self, X, "fit")
        check_finite_input(self, Y, "fit", name="Y")
        X, Y = validate_data(self, X, Y, multi_output=True, y_numeric=True, dtype=np.float64)
        N = X.shape[0]
        self._check_n_samples(N)
        self.y_ndim_ = Y.ndim
        Y2 = Y.reshape(N, -1)
        self.n_outputs_ = Y2.shape[1]
        Mx, My, K = X.shape[1], Y2.shape[1], int(self.n_atoms)

        self.y_bounds_ = output_bounds(Y2)
        if self.standardize:
            xs = InputScaler(self.input_scaling).fit(X).scaler_
            self.x_mean_ = xs.mean_ if xs.with_mean else np.zeros(Mx)
            self.x_scale_ = xs.scale_ if xs.with_std else np.ones(Mx)
            self.y_mean_, self.y_scale_ = Y2.mean(axis=0), Y2.std(axis=0)
            self.y_scale_[self.y_scale_ == 0] = 1.0
        else:
            self.x_mean_, self.x_scale_ = np.zeros(Mx), np.ones(Mx)
            self.y_mean_, self.y_scale_ = np.zeros(My), np.ones(My)
        Xs = (X - self.x_mean_) / self.x_scale_
        Ys = (Y2 - self.y_mean_) / self.y_scale_
        V = np.ascontiguousarray(np.hstack([Xs, Ys]))

        Sigma, self.eta_ = kern.logit_prior(self.logit_kernel, Xs, Ys, float(self.eta_scale))
        Lw, self.sigma_jitter_ = kern.cholesky_with_jitter(Sigma, self.eta_)
        Sigma = np.ascontiguousarray(Sigma + self.sigma_jitter_ * np.eye(N))

        rs = check_random_state(self.random_state)
        seed_fit, seed_pred = rs.randint(0, np.iinfo(np.int32).max, size=2)
        rng = np.random.default_rng(int(seed_fit))
        self.predict_seed_ = int(seed_pred)

        state = self._initial_state(V, Mx, K, rng, float(self.w_prior_mean))
        data = kern.BSRData(V=V, Mx=Mx, Sigma=Sigma, Lw=np.ascontiguousarray(Lw))
        hyper = kern.BSRHyper(
            a0=float(self.a0),
            b0=float(self.b0),
            a_xy=None if self.a_xy is None else float(self.a_xy),
            b_xy=None if self.b_xy is None else float(self.b_xy),
            w_mean=float(self.w_prior_mean),
            noise=self.noise,
        )

        n_keep = (self.n_iter - self.n_burn_in) // self.thin  # >= 1 (_check_params)
        keep_at = set(self.n_iter - 1 - self.thin * np.arange(n_keep))
        Dx = np.empty((n_keep, K, Mx))
        Dy = np.empty((n_keep, K, My))
        Ws = np.empty((n_keep, N, K))
        gs = np.empty(n_keep)
        gxy = np.empty(n_keep)
        gnx = np.empty(n_keep)
        gny = np.empty(n_keep)
        names = (
            "log_likelihood",
            "g_xy",
            "g_s",
            "g_x",
            "g_y",
            "g_nx",
            "g_ny",
            "active_atoms",
            "acceptance",
        )
        trace = {name: np.empty(self.n_iter) for name in names}
        if self.noise == "shared":  # g_nx = g_ny = g_xy: not traced twice
            del trace["g_nx"], trace["g_ny"]

        level = logging.INFO if self.verbose else logging.DEBUG
        kern.keep_freed_memory()  # the sweeps' temporaries are reused, not page-faulted in again every sweep
        t0 = time.perf_counter()
        slot = 0
        for it in range(self.n_iter):
            try:
                _, stats = kern.gibbs_sweep(
                    state, data, hyper, rng, self.w_update, self.atom_update
                )
            except (np.linalg.LinAlgError, ZeroDivisionError, ValueError) as exc:
                raise SamplerError(
                    f"BayesianSR: non-finite or degenerate sampler state at sweep {it} ({exc}); "
                    f"g_s, g_xy, g_x, g_y, g_nx, g_ny = {state.prec.tolist()}; check the scale of X and Y "
                    f"(standardize=True) and the hyper-priors a0, b0"
                ) from exc
            g_s, g_xy, g_x, g_y, g_nx, g_ny = state.prec
            if not (
                np.all(np.isfinite(stats))
                and np.all(np.isfinite(state.prec))
                and np.all(state.prec > 0)
            ):
                raise SamplerError(
                    f"BayesianSR: non-finite or degenerate sampler state at sweep {it}: "
                    f"log-likelihood={stats[0]!r}, g_s={g_s!r}, g_xy={g_xy!r}, g_x={g_x!r}, g_y={g_y!r}; "
                    f"check the scale of X and Y (standardize=True) and the hyper-priors a0, b0"
                )
            for name, val in zip(
                names, (stats[0], g_xy, g_s, g_x, g_y, g_nx, g_ny, stats[1], stats[2])
            ):
                if name in trace:
                    trace[name][it] = val
            if it in keep_at:
                Dx[slot] = state.D[:, :Mx]
                Dy[slot] = state.D[:, Mx:]
                Ws[slot] = state.W
                gs[slot], gxy[slot], gnx[slot], gny[slot] = g_s, g_xy, g_nx, g_ny
                slot += 1
            if (it + 1) % _LOG_EVERY == 0 or it + 1 == self.n_iter:
                logger.log(
                    level,
                    "sweep %d/%d: log-lik %.1f, g_xy %.3g, g_s %.3g, active atoms %d, acceptance %.2f (%.1f s)",
                    it + 1,
                    self.n_iter,
                    stats[0],
                    g_xy,
                    g_s,
                    int(stats[1]),
                    stats[2],
                    time.perf_counter() - t0,
                )
        self.fit_seconds_ = time.perf_counter() - t0
        self.trace_ = trace
        self.samples_ = {
            "Dx": Dx,
            "Dy": Dy,
            "W": Ws,
            "g_s": gs,
            "g_xy": gxy,
            "g_nx": gnx,
            "g_ny": gny,
        }
        self.X_train_ = Xs
        return self

    @staticmethod
    def _initial_state(V, Mx, K, rng, w_mean=0.0):
        """A random start: W = w_mean (every atom on with probability sigmoid(w_mean): 1/2 in the paper's model),
        codes and atoms at the data scale."""
        N, M = V.shape
        with np.errstate(over="ignore"):
            v2 = max(float(np.mean(V * V)), 1e-12)
        if not np.isfinite(v2):
            raise SamplerError(
                "BayesianSR: non-finite or degenerate sampler state at sweep 0 (initial state): the mean square "
                "of the (standardized) data overflows; use standardize=True or rescale X and Y"
            )
        g_s, g_xy, g_d = 1.0, 1.0 / v2, K / (2.0 * v2)
        D = np.ascontiguousarray(rng.standard_normal((K, M)) / np.sqrt(g_d))
        B = (rng.random((N, K)) < 1.0 / (1.0 + np.exp(-w_mean))).astype(np.int8)
        S = rng.standard_normal((N, K))
        W = np.full((N, K), float(w_mean))
        R = np.ascontiguousarray(V - (B * S) @ D)
        norms = np.einsum("km,km->k", D, D)
        prec = np.array([g_s, g_xy, g_d, g_d, g_xy, g_xy])
        return kern.BSRState(D=D, norms=norms, B=B, S=S, W=W, R=R, prec=prec)

    # ------------------------------------------------------------------------------------------------------
    def _predict_samples(self):
        """The retained samples the prediction uses: the last ``n_predict_samples`` (all for None)."""
        _validate(
            {
                k: self._parameter_constraints[k]
                for k in ("prediction", "prediction_weighting", "n_predict_samples")
            },
            {
                "prediction": self.prediction,
                "prediction_weighting": self.prediction_weighting,
                "n_predict_samples": self.n_predict_samples,
            },
            "BayesianSR",
        )
        L = self.samples_["g_xy"].shape[0]
        n = L if self.n_predict_samples is None else int(self.n_predict_samples)
        if n > L:
            raise InputError(
                f"n_predict_samples={n} exceeds the {L} retained samples of the fit; expected an integer in "
                f"[1, {L}] or None (all)"
            )
        return {k: v[L - n :] for k, v in self.samples_.items()}

    def _predict_draws(self, X, n_neighbors):
        """Per test point and used sample: standardized y draws (T, L, My) and log N(x_t; D^x alpha_t, 1/g I)."""
        s = self._predict_samples()
        j = self.n_neighbors if n_neighbors is None else n_neighbors
        N = self.X_train_.shape[0]
        _validate({"n_neighbors": [_count(1, N)]}, {"n_neighbors": j}, "BayesianSR.predict")
        j = int(j)
        Xs = np.ascontiguousarray((X - self.x_mean_) / self.x_scale_)
        nbr = kern.nearest_neighbours(Xs, self.X_train_, j)
        seeds = kern.point_seeds(Xs.view(np.uint64), np.uint64(self.predict_seed_))
        T, L, My = X.shape[0], s["Dx"].shape[0], s["Dy"].shape[2]
        out_y = np.empty((T, L, My))
        out_ll = np.empty((T, L))
        if self.prediction == "paper-text":
            kern.predict_kernel_prior_codes(
                Xs, nbr, s["Dx"], s["Dy"], s["W"], s["g_s"], s["g_nx"], seeds, out_y, out_ll
            )
        else:
            kern.predict_kernel(
                Xs,
                nbr,
                s["Dx"],
                s["Dy"],
                s["W"],
                s["g_s"],
                s["g_nx"],
                int(self.n_predict_sweeps),
                seeds,
                out_y,
                out_ll,
            )
        return out_y, out_ll, s

    def _weights(self, out_ll):
        """Sample weights (T, L): uniform, or the paper's self-normalized beta_l (prediction_weighting)."""
        if self.prediction_weighting == "likelihood":
            lw = out_ll - out_ll.max(axis=1, keepdims=True)
            wts = np.exp(lw)
            return wts / wts.sum(axis=1, keepdims=True)
        return np.full(
            out_ll.shape, 1.0 / out_ll.shape[1]
        )  # "uniform" (validated by _predict_samples)

    def predict_draws(self, X, n_neighbors=None):
        """Per-retained-sample predictions and the weights :meth:`predict` averages them with.

        Parameters
        ----------
        X : array of shape (n_test, n_features)
        n_neighbors : int or None
            Overrides the fitted ``n_neighbors`` for this call.

        Returns
        -------
        draws : ndarray of shape (n_test, n_samples, n_outputs)
            ``D^y alpha_t`` of each retained posterior sample the prediction uses (the last
            ``n_predict_samples``; all, ``samples_["g_xy"].size``, for None), in the units of Y (mapped back from
            the standardized scale); no noise added.
        weights : ndarray of shape (n_test, n_samples)
            Rows sum to 1: uniform, or the paper's self-normalized beta_l (``prediction_weighting``).
            ``predict(X)`` equals ``einsum("tl,tlm->tm", weights, draws)`` up to rounding.

        Raises InputError for an invalid ``n_neighbors`` and the scikit-learn errors for X of the wrong width.
        """
        check_is_fitted(self, "samples_")
        check_finite_input(self, X)
        X = validate_data(self, X, reset=False, dtype=np.float64)
        ys, ws = [], []
        for i in range(0, max(X.shape[0], 1), _CHUNK):
            out_y, out_ll, _ = self._predict_draws(X[i : i + _CHUNK], n_neighbors)
            ys.append(out_y * self.y_scale_ + self.y_mean_)
            ws.append(self._weights(out_ll))
        return np.concatenate(ys), np.concatenate(ws)

    def predict(self, X, return_std=False, n_neighbors=None):
        """Posterior predictive mean (and per-output std with ``return_std``) in the units of Y.

        The mean is clipped to the training range of each output widened by half its width on each side
        (:func:`bsrbench.models.scaling.output_bounds`); the std is not changed.

        The std combines the spread of the per-sample predictions and the noise variance 1/g_xy (1/g_ny, the
        output rows' noise, with ``noise="separate"``). ``n_neighbors`` overrides the fitted value for this call.
        """
        y, std, _, _ = self._predict_pass(X, n_neighbors, draws=False)
        return (y, std) if return_std else y

    def predict_with_draws(self, X, n_neighbors=None):
        """:meth:`predict` with ``return_std=True`` and :meth:`predict_draws` from one pass of the sampler over
        the test points: ``(mean, std, draws, weights)``, each equal to what those two methods return."""
        return self._predict_pass(X, n_neighbors, draws=True)

    def _predict_pass(self, X, n_neighbors, draws):
        """(mean, std, draws or None, weights or None) of :meth:`predict_with_draws`, chunk by chunk."""
        check_is_fitted(self, "samples_")
        check_finite_input(self, X)
        X = validate_data(self, X, reset=False, dtype=np.float64)
        parts = [
            self._predict_chunk(X[i : i + _CHUNK], n_neighbors, draws)
            for i in range(0, max(X.shape[0], 1), _CHUNK)
        ]
        y = clip_to_bounds(np.concatenate([p[0] for p in parts]), self.y_bounds_)
        std = np.concatenate([p[1] for p in parts])
        if self.y_ndim_ == 1:
            y, std = y.ravel(), std.ravel()
        if not draws:
            return y, std, None, None
        return y, std, np.concatenate([p[2] for p in parts]), np.concatenate([p[3] for p in parts])

    def _predict_chunk(self, X, n_neighbors, draws=False):
        out_y, out_ll, s = self._predict_draws(X, n_neighbors)
        wts = self._weights(out_ll)
        mean = np.einsum("tl,tlm->tm", wts, out_y)
        spread = np.einsum("tl,tlm->tm", wts, (out_y - mean[:, None, :]) ** 2)
        noise = wts @ (1.0 / s["g_ny"])
        mean_y = mean * self.y_scale_ + self.y_mean_
        std = np.sqrt(spread + noise[:, None]) * self.y_scale_
        if not draws:
            return mean_y, std
        return mean_y, std, out_y * self.y_scale_ + self.y_mean_, wts


def training_error(estimator, X_train, Y_train, inverse=None):
    """The paper's error (mean over angles of the per-angle RMS, degrees) of a fitted model on its training frames.

    Shown beside the test error, it tells overfitting (a small training error and a large test error) from
    underfitting. ``X_train``, ``Y_train``: the frames the model was fitted on, ``Y_train`` in degrees;
    ``inverse``: the map from the model's output space back to degrees (a pose transform's ``inverse``; None for
    the identity). PM predicts a training frame as any test frame, from ``x`` alone (its nearest training input
    is itself).
    """
    Z = estimator.predict(X_train)
    return mean_angle_error(Y_train, Z if inverse is None else inverse(Z))


def warm_up():
    """Load the sampler's numba kernels from the cache (tiny fits of each kernel variant), e.g. in a job server
    before it forks the jobs."""
    rng = np.random.default_rng(0)
    X, Y = rng.standard_normal((12, 3)), rng.standard_normal((12, 2))
    tiny = dict(n_atoms=2, n_neighbors=1, n_iter=2, n_burn_in=1, thin=1, random_state=0)
    BayesianSR(**tiny).fit(X, Y).predict(X[:2])
    BayesianSR(**tiny, w_update="mh", atom_update="single").fit(X, Y)
    BayesianSR(**tiny, noise="separate", w_prior_mean=-1.0, prediction="paper-text").fit(
        X, Y
    ).predict(X[:2])
