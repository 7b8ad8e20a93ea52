"""The explicit Runge-Kutta method DOP853 of Dormand and Prince, with error control.

Owns the adaptive integrator of the certificate's simulations
(:mod:`youbot_opt.trajopt.simulate`): Hairer's ``dop853.f`` (Hairer, Norsett and
Wanner, *Solving ODEs I*, II.10) step for step as SciPy's
``solve_ivp(method="DOP853")``, without importing ``scipy.integrate``. The state
is a stack of rows, each held to the tolerances; :class:`Dop853` takes one step
at a time (a :class:`~youbot_opt.dynamics.stepper.Stepper`), so a caller can stop
on a knot, an event or a deadline.

>>> stepper = Dop853(fun, 0.0, y0, rtol=1e-10, atol=1e-12, t_bound=1.0)  # doctest: +SKIP
>>> while stepper.t < 1.0 and stepper.step(1.0): pass  # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.dynamics.stepper import (
    MAX_FACTOR,
    MIN_FACTOR,
    SAFETY,
    TOO_SMALL_STEP,
    Rhs,
    Stepper,
    min_step,
    next_step_size,
    trial_step,
)

__all__ = ["Dop853"]

_EXPONENT = -1.0 / 8.0  # -1 / (error estimator order + 1)
_N_STAGES = 12

_C = np.array([
    0.0, 0.526001519587677318785587544488e-01, 0.789002279381515978178381316732e-01,
    0.118350341907227396726757197510, 0.281649658092772603273242802490,
    0.333333333333333333333333333333, 0.25, 0.307692307692307692307692307692,
    0.651282051282051282051282051282, 0.6, 0.857142857142857142857142857142, 1.0, 1.0, 0.1,
    0.2, 0.777777777777777777777777777778,
])  # fmt: skip

# Nonzero entries of the Butcher matrix by row (rows 13-15: the dense output's extra stages).
_A_ROWS: dict[int, dict[int, float]] = {
    1: {0: 5.26001519587677318785587544488e-2},
    2: {0: 1.97250569845378994544595329183e-2, 1: 5.91751709536136983633785987549e-2},
    3: {0: 2.95875854768068491816892993775e-2, 2: 8.87627564304205475450678981324e-2},
    4: {0: 2.41365134159266685502369798665e-1, 2: -8.84549479328286085344864962717e-1,
        3: 9.24834003261792003115737966543e-1},
    5: {0: 3.7037037037037037037037037037e-2, 3: 1.70828608729473871279604482173e-1,
        4: 1.25467687566822425016691814123e-1},
    6: {0: 3.7109375e-2, 3: 1.70252211019544039314978060272e-1,
        4: 6.02165389804559606850219397283e-2, 5: -1.7578125e-2},
    7: {0: 3.70920001185047927108779319836e-2, 3: 1.70383925712239993810214054705e-1,
        4: 1.07262030446373284651809199168e-1, 5: -1.53194377486244017527936158236e-2,
        6: 8.27378916381402288758473766002e-3},
    8: {0: 6.24110958716075717114429577812e-1, 3: -3.36089262944694129406857109825,
        4: -8.68219346841726006818189891453e-1, 5: 2.75920996994467083049415600797e1,
        6: 2.01540675504778934086186788979e1, 7: -4.34898841810699588477366255144e1},
    9: {0: 4.77662536438264365890433908527e-1, 3: -2.48811461997166764192642586468,
        4: -5.90290826836842996371446475743e-1, 5: 2.12300514481811942347288949897e1,
        6: 1.52792336328824235832596922938e1, 7: -3.32882109689848629194453265587e1,
        8: -2.03312017085086261358222928593e-2},
    10: {0: -9.3714243008598732571704021658e-1, 3: 5.18637242884406370830023853209,
         4: 1.09143734899672957818500254654, 5: -8.14978701074692612513997267357,
         6: -1.85200656599969598641566180701e1, 7: 2.27394870993505042818970056734e1,
         8: 2.49360555267965238987089396762, 9: -3.0467644718982195003823669022},
    11: {0: 2.27331014751653820792359768449, 3: -1.05344954667372501984066689879e1,
         4: -2.00087205822486249909675718444, 5: -1.79589318631187989172765950534e1,
         6: 2.79488845294199600508499808837e1, 7: -2.85899827713502369474065508674,
         8: -8.87285693353062954433549289258, 9: 1.23605671757943030647266201528e1,
         10: 6.43392746015763530355970484046e-1},
    12: {0: 5.42937341165687622380535766363e-2, 5: 4.45031289275240888144113950566,
         6: 1.89151789931450038304281599044, 7: -5.8012039600105847814672114227,
         8: 3.1116436695781989440891606237e-1, 9: -1.52160949662516078556178806805e-1,
         10: 2.01365400804030348374776537501e-1, 11: 4.47106157277725905176885569043e-2},
    13: {0: 5.61675022830479523392909219681e-2, 6: 2.53500210216624811088794765333e-1,
         7: -2.46239037470802489917441475441e-1, 8: -1.24191423263816360469010140626e-1,
         9: 1.5329179827876569731206322685e-1, 10: 8.20105229563468988491666602057e-3,
         11: 7.56789766054569976138603589584e-3, 12: -8.298e-3},
    14: {0: 3.18346481635021405060768473261e-2, 5: 2.83009096723667755288322961402e-2,
         6: 5.35419883074385676223797384372e-2, 7: -5.49237485713909884646569340306e-2,
         10: -1.08347328697249322858509316994e-4, 11: 3.82571090835658412954920192323e-4,
         12: -3.40465008687404560802977114492e-4, 13: 1.41312443674632500278074618366e-1},
    15: {0: -4.28896301583791923408573538692e-1, 5: -4.69762141536116384314449447206,
         6: 7.68342119606259904184240953878, 7: 4.06898981839711007970213554331,
         8: 3.56727187455281109270669543021e-1, 12: -1.39902416515901462129418009734e-3,
         13: 2.9475147891527723389556272149, 14: -9.15095847217987001081870187138},
}  # fmt: skip

# The dense output's coefficients (rows of F[3:] = h D K).
_D_ROWS: dict[int, dict[int, float]] = {
    0: {0: -0.84289382761090128651353491142e+1, 5: 0.56671495351937776962531783590,
        6: -0.30689499459498916912797304727e+1, 7: 0.23846676565120698287728149680e+1,
        8: 0.21170345824450282767155149946e+1, 9: -0.87139158377797299206789907490,
        10: 0.22404374302607882758541771650e+1, 11: 0.63157877876946881815570249290,
        12: -0.88990336451333310820698117400e-1, 13: 0.18148505520854727256656404962e+2,
        14: -0.91946323924783554000451984436e+1, 15: -0.44360363875948939664310572000e+1},
    1: {0: 0.10427508642579134603413151009e+2, 5: 0.24228349177525818288430175319e+3,
        6: 0.16520045171727028198505394887e+3, 7: -0.37454675472269020279518312152e+3,
        8: -0.22113666853125306036270938578e+2, 9: 0.77334326684722638389603898808e+1,
        10: -0.30674084731089398182061213626e+2, 11: -0.93321305264302278729567221706e+1,
        12: 0.15697238121770843886131091075e+2, 13: -0.31139403219565177677282850411e+2,
        14: -0.93529243588444783865713862664e+1, 15: 0.35816841486394083752465898540e+2},
    2: {0: 0.19985053242002433820987653617e+2, 5: -0.38703730874935176555105901742e+3,
        6: -0.18917813819516756882830838328e+3, 7: 0.52780815920542364900561016686e+3,
        8: -0.11573902539959630126141871134e+2, 9: 0.68812326946963000169666922661e+1,
        10: -0.10006050966910838403183860980e+1, 11: 0.77771377980534432092869265740,
        12: -0.27782057523535084065932004339e+1, 13: -0.60196695231264120758267380846e+2,
        14: 0.84320405506677161018159903784e+2, 15: 0.11992291136182789328035130030e+2},
    3: {0: -0.25693933462703749003312586129e+2, 5: -0.15418974869023643374053993627e+3,
        6: -0.23152937917604549567536039109e+3, 7: 0.35763911791061412378285349910e+3,
        8: 0.93405324183624310003907691704e+2, 9: -0.37458323136451633156875139351e+2,
        10: 0.10409964950896230045147246184e+3, 11: 0.29840293426660503123344363579e+2,
        12: -0.43533456590011143754432175058e+2, 13: 0.96324553959188282948394950600e+2,
        14: -0.39177261675615439165231486172e+2, 15: -0.14972683625798562581422125276e+3},
}  # fmt: skip


def _dense_matrix(rows: dict[int, dict[int, float]], shape: tuple[int, int]) -> Array:
    out = np.zeros(shape)
    for i, row in rows.items():
        for j, value in row.items():
            out[i, j] = value
    out.setflags(write=False)
    return out


_A = _dense_matrix(_A_ROWS, (16, 16))
_B = _A[_N_STAGES, :_N_STAGES]
_E3 = np.zeros(_N_STAGES + 1)  # B minus the 3rd-order weights (bhh of dop853.f)
_E3[:-1] = _B
_E3[0] -= 0.244094488188976377952755905512
_E3[8] -= 0.733846688281611857341361741547
_E3[11] -= 0.220588235294117647058823529412e-1
_E5 = _dense_matrix(
    {0: {0: 0.1312004499419488073250102996e-1, 5: -0.1225156446376204440720569753e+1,
         6: -0.4957589496572501915214079952, 7: 0.1664377182454986536961530415e+1,
         8: -0.3503288487499736816886487290, 9: 0.3341791187130174790297318841,
         10: 0.8192320648511571246570742613e-1, 11: -0.2235530786388629525884427845e-1}},
    (1, _N_STAGES + 1),
)[0]  # fmt: skip
_D = _dense_matrix(_D_ROWS, (4, 16))
_E53 = np.stack([_E5, _E3])  # both error estimates in one product


class Dop853(Stepper):
    """DOP853 integration of a stack of rows, one accepted step at a time.

    A :class:`~youbot_opt.dynamics.stepper.Stepper` (its parameters and
    attributes): :meth:`step` takes one accepted step towards ``t_bound``
    without passing it; :meth:`dense` evaluates the last step's continuous
    extension. The error of a step is measured per row (the scaled 5th/3rd-order
    estimate of ``dop853.f``, RMS over the row) and the largest row's decides:
    with one row this is SciPy's DOP853 exactly.
    """

    error_order = 7

    def __init__(
        self,
        fun: Rhs,
        t0: float,
        y0: Array,
        *,
        rtol: float,
        atol: float,
        t_bound: float,
        first_step: float | None = None,
        f0: Array | None = None,
    ) -> None:
        super().__init__(
            fun, t0, y0, rtol=rtol, atol=atol, t_bound=t_bound, first_step=first_step, f0=f0
        )
        rows, n = self.y.shape
        self._KY = np.empty((17, rows * n))  # y, then the stages (13-15 for the dense output)
        self._K = self._KY[1:].reshape(16, rows, n)
        self._K_flat = self._KY[1:]
        self._coef = np.ones((16, 17))  # [1, h A]: row s makes stage s from KY
        self._F = np.empty((7, rows * n))  # the dense output's polynomial
        self._dense_ready = False

    def step(self, t_bound: float) -> bool:
        """Take one accepted step towards ``t_bound``, at most to ``t_bound``.

        See :meth:`Stepper.step <youbot_opt.dynamics.stepper.Stepper.step>`.
        """
        t, y, fun = self.t, self.y, self.fun
        rows, n = y.shape
        smallest = min_step(t)
        h_abs = max(self.h_abs, smallest) if self.h_abs == self.h_abs else self.h_abs
        wanted, rejected = h_abs, False
        KY, K = self._KY, self._K
        KY[0] = y.reshape(-1)  # row 0 of KY is y, rows 1.. the stages: one product per stage
        coef = self._coef
        while True:
            if not h_abs >= smallest:  # NaN-safe: a NaN size fails too
                self.message = TOO_SMALL_STEP
                return False
            t_new, h, cut = trial_step(t, h_abs, t_bound)
            h_abs = abs(h)
            np.multiply(_A, h, out=coef[:, 1:])  # coef = [1, h A]
            K[0] = self.f
            for s in range(1, _N_STAGES + 1):  # the 12 stages, then f at the step's end
                x = np.dot(coef[s, : s + 1], KY[: s + 1])
                K[s] = fun(t + _C[s] * h, x.reshape(rows, n))
            self.nfev += _N_STAGES
            y_new = x.reshape(rows, n)  # stage 12 is the solution (B = A[12]): FSAL
            scale = self.atol + np.maximum(np.abs(y), np.abs(y_new)) * self.rtol
            error = self._error_norm(h, scale)
            if error < 1.0:
                factor = MAX_FACTOR
                if error > 0.0:
                    factor = min(MAX_FACTOR, SAFETY * error**_EXPONENT)
                if rejected:
                    factor = min(1.0, factor)
                break
            h_abs *= max(MIN_FACTOR, SAFETY * error**_EXPONENT)
            rejected = True
        h_next = next_step_size(h_abs, factor, wanted=wanted, cut=cut, rejected=rejected)
        self._accept(t_new, y_new, K[_N_STAGES].copy(), h, h_next)
        self._dense_ready = False
        return True

    def _error_norm(self, h: float, scale: Array) -> float:
        """Return the step's scaled error: the largest row's (NaN or inf if not finite)."""
        rows, n = scale.shape
        stages = self._K_flat[: _N_STAGES + 1]
        with np.errstate(all="ignore"):  # a state that is not finite: rejected, then failed
            err = (np.dot(_E53, stages) / scale.reshape(-1)).reshape(2, rows, n)
            sq = np.einsum("krn,krn->kr", err, err)  # squared norms of the 5th and 3rd order
            denom = sq[0] + 0.01 * sq[1]
            zero = denom == 0.0  # NaN stays NaN, so the step is rejected
            norms = abs(h) * sq[0] / np.sqrt(np.where(zero, 1.0, denom) * n)
        return float(np.max(np.where(zero, 0.0, norms)))

    def dense(self, t: Array) -> Array:
        """Evaluate the last step's continuous extension (7th order) at times ``t``.

        The first call after a step evaluates ``fun`` three more times (the
        extension's stages): make it before ``fun`` changes.

        See :meth:`Stepper.dense <youbot_opt.dynamics.stepper.Stepper.dense>`.
        """
        rows, n = self.y.shape
        if not self._dense_ready:
            self._prepare_dense(rows, n)
        x = (np.asarray(t, dtype=float) - self.t_old) / self._h
        # SciPy's Horner scheme in x and 1 - x, expanded: F[i] times x^a (1 - x)^b
        u = 1.0 - x
        x2, xu = x * x, x * u
        weights = np.empty((x.size, 7))
        weights[:, 0] = x
        weights[:, 1] = xu
        weights[:, 2] = x * xu
        weights[:, 3] = xu * xu
        weights[:, 4] = x2 * xu * u
        weights[:, 5] = xu * xu * xu
        weights[:, 6] = x2 * xu * xu * u
        out = np.dot(weights, self._F)
        out += self.y_old.reshape(-1)
        return out.reshape(-1, rows, n)

    def _prepare_dense(self, rows: int, n: int) -> None:
        K, KY, h, t_old = self._K, self._KY, self._h, self.t_old
        KY[0] = self.y_old.reshape(-1)
        coef = self._coef
        np.multiply(_A, h, out=coef[:, 1:])
        for s in range(_N_STAGES + 1, 16):
            x = np.dot(coef[s, : s + 1], KY[: s + 1])
            K[s] = self.fun(t_old + _C[s] * h, x.reshape(rows, n))
        self.nfev += 3
        delta = self.y.reshape(-1) - KY[0]
        f_old, f = self._K_flat[0], self._K_flat[_N_STAGES]  # the step's, whatever refresh did
        F = self._F
        F[0] = delta
        F[1] = h * f_old - delta
        F[2] = 2.0 * delta - h * (f + f_old)
        F[3:] = h * np.dot(_D, self._K_flat)
        self._dense_ready = True
