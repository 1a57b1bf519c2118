"""MuJoCo's contacts with elliptic friction cones in the sand's implicit solve
(`implicit_solve._implicit_step`), as the rows MuJoCo makes for them (`constraint_rows`, kind
CONE: a contact's condim rows together, its normal row first).

A cone's force is MuJoCo's own function of its rows' jar = J qvel+ / dt - start (m/s^2 or
rad/s^2; `constraint_rows`' ROW_START), the force of mj_constraintUpdate that MuJoCo's Newton
solver minimises for: in the cone's regular dual space U = diag(mu, friction) jar,
N = U_0, T = |U_1..|, it is none in the top zone (separating), each row's soft constraint
-D jar in the bottom zone (sticking), and in the middle zone (sliding) on the cone's
surface, the negative gradient of Dm (N - mu T)^2 / 2, Dm = D_0 / (mu^2 (1 + mu^2)), which
is not linear in jar. The solve takes each cone linearised, f ~ f(jar_k) - H (jar - jar_k)
(H the Hessian of the cone's cost, MuJoCo's cone Hessian in the middle zone), and solves
again from a new point until, at the solution, every cone's force is MuJoCo's to
CONE_TOLERANCE (Newton's method). Its step is damped where it would not reduce the
residual of the whole system (the plates, joints and rows in their sets): a backtracking
line search on its squared norm, as Newton's method needs on the cone's kinks and stiff
sliding (a foot on a rigid rock at impratio 100 oscillated without it).
"""
import numpy as np
from numba import njit

from ..kernel_cache import forget_stale
from .active_set import STATE
from .constraint_rows import row_jar
from .layout import (CONE, CONE_ROWS, ROW_AREF, ROW_D, ROW_DIM, ROW_FORCE, ROW_FRICTION,
                     ROW_HESSIAN, ROW_JAR, ROW_KIND, ROW_LINEAR, ROW_POINT, ROW_PUSH, ROW_REPORT,
                     ROW_START, ROW_TRIAL)

#: A cone's zones (its set, flags row STATE): top (separating: no force), bottom (sticking:
#: every row its soft constraint -D jar) and middle (sliding: on the cone's surface).
TOP, BOTTOM, MIDDLE = 0, 1, 2
#: A cone's linearisation holds when, at the solve's end velocities, its force differs
#: from MuJoCo's by at most this fraction of that force's size.
CONE_TOLERANCE = 1e-6
#: Newton steps of the cones a step takes at most; halvings of a step its line search tries
#: at most; and the decrease of the squared residual it asks of a step of length alpha,
#: 1 - 2 ARMIJO alpha (Armijo's rule).
CONE_ITERATIONS = 12
HALVINGS = 10
ARMIJO = 1e-4
#: The columns handed to the kernels below as numpy integers: a kernel taking a column then
#: compiles once, where a plain int constant would compile it once for each literal value.
_POINT, _JAR, _TRIAL = np.int64(ROW_POINT), np.int64(ROW_JAR), np.int64(ROW_TRIAL)


@njit(cache=True, inline='always')
def _cone_dim(rows, r):
    """The rows of the cone that starts at row r (its condim), 0 where none starts there."""
    return int(rows[r, ROW_DIM]) if rows[r, ROW_KIND] == CONE else 0


@njit(cache=True, inline='always')
def _dual(rows, r, dim, column):
    """(mu, N, T) of the cone whose dim rows start at row r, at the jar in rows[:, column]:
    its regular dual space U = diag(mu, friction) jar, N = U_0, T = |U_1..|."""
    mu = rows[r, ROW_FRICTION]
    tangent = 0.0
    for a in range(1, dim):
        value = rows[r + a, column] * rows[r + a, ROW_FRICTION]
        tangent += value * value
    return mu, rows[r, column] * mu, np.sqrt(tangent)


@njit(cache=True)
def cone_zone(rows, r, dim, column):
    """The zone (TOP, BOTTOM, MIDDLE) of the cone whose dim rows start at row r, at the jar
    in rows[:, column], as MuJoCo's mj_constraintUpdate decides it."""
    mu, normal, tangent = _dual(rows, r, dim, column)
    if normal >= mu * tangent or (tangent <= 0.0 and normal >= 0.0):
        return TOP
    if mu * normal + tangent <= 0.0 or (tangent <= 0.0 and normal < 0.0):
        return BOTTOM
    return MIDDLE


@njit(cache=True)
def cone_force(rows, r, dim, zone, column, force, hessian):
    """MuJoCo's force (N or N m, into force[:dim]) of the cone at rows r .. r + dim - 1 at
    the jar in rows[:, column] in `zone`, and the Hessian (into hessian[:dim, :dim]) of the
    cost whose negative gradient it is (mj_constraintUpdate's force and cone Hessian)."""
    for a in range(dim):
        force[a] = 0.0
        for b in range(dim):
            hessian[a, b] = 0.0
    if zone == TOP:
        return
    if zone == BOTTOM:
        for a in range(dim):
            force[a] = -rows[r + a, ROW_D] * rows[r + a, column]
            hessian[a, a] = rows[r + a, ROW_D]
        return
    mu, normal, tangent = _dual(rows, r, dim, column)
    scaled = rows[r, ROW_D] / (mu * mu * (1.0 + mu * mu))
    force[0] = -scaled * (normal - mu * tangent) * mu
    hessian[0, 0] = 1.0
    for a in range(1, dim):
        u_a = rows[r + a, column] * rows[r + a, ROW_FRICTION]
        force[a] = -force[0] / tangent * u_a * rows[r + a, ROW_FRICTION]
        hessian[0, a] = hessian[a, 0] = -mu / tangent * u_a
        for b in range(1, dim):
            u_b = rows[r + b, column] * rows[r + b, ROW_FRICTION]
            hessian[a, b] = mu * normal / tangent ** 3 * u_a * u_b
        hessian[a, a] += mu * mu - mu * normal / tangent
    for a in range(dim):
        for b in range(dim):
            hessian[a, b] *= scaled * rows[r + a, ROW_FRICTION] * rows[r + b, ROW_FRICTION]


@njit(cache=True)
def _linearise(rows, r, dim, timestep, flags):
    """The cone at rows r .. r + dim - 1 linearised at its point (ROW_POINT), in the zone
    there (into flags STATE): f ~ f(point) - H (jar - point) = ROW_LINEAR - H jar, and with
    jar = J qvel+ / dt - start its push dt (ROW_LINEAR + H start) (dt J^T f adds J^T H J to
    the system and J^T push to the right-hand side, `cone_terms`)."""
    zone = cone_zone(rows, r, dim, _POINT)
    flags[STATE, r] = zone
    force = np.empty(CONE_ROWS)
    hessian = rows[r:r + dim, ROW_HESSIAN:ROW_HESSIAN + dim]
    cone_force(rows, r, dim, zone, _POINT, force, hessian)
    for a in range(dim):
        linear = force[a]
        for b in range(dim):
            linear += hessian[a, b] * rows[r + b, ROW_POINT]
        rows[r + a, ROW_LINEAR] = linear
    for a in range(dim):
        push = rows[r + a, ROW_LINEAR]
        for b in range(dim):
            push += hessian[a, b] * rows[r + b, ROW_START]
        rows[r + a, ROW_PUSH] = timestep * push


@njit(cache=True)
def _linearise_all(constraints, column, timestep):
    """Every cone linearised at the jar in rows[:, column] (into ROW_POINT; `_linearise`).
    Returns the cones."""
    rows, flags, n = constraints[3], constraints[4], constraints[5]
    cones = 0
    for r in range(n):
        dim = _cone_dim(rows, r)
        if dim == 0:
            continue
        for a in range(r, r + dim):
            rows[a, ROW_POINT] = rows[a, column]
        _linearise(rows, r, dim, timestep, flags)
        cones += 1
    return cones


@njit(cache=True)
def cone_start(constraints, timestep):
    """A step's start of its cones (after `constraint_rows.constraint_start`, which sets their
    ROW_START): each linearised at its jar without a change of velocity, -aref (ROW_JAR).
    Returns the cones."""
    rows, n = constraints[3], constraints[5]
    for r in range(n):
        if rows[r, ROW_KIND] == CONE:
            rows[r, ROW_JAR] = -rows[r, ROW_AREF]
    return _linearise_all(constraints, _JAR, timestep)


@njit(cache=True)
def cone_terms(constraints, system, rhs):
    """The cones' terms of the implicit system by their linearisation: J^T H J into the
    system, J^T push into the right-hand side (`_linearise`)."""
    jac, columns, counts, rows, n = (constraints[0], constraints[1], constraints[2],
                                      constraints[3], constraints[5])
    for r in range(n):
        dim = _cone_dim(rows, r)
        for a in range(r, r + dim):
            row_a, used_a = jac[a], columns[a, :counts[a]]
            push = rows[a, ROW_PUSH]
            for i in used_a:
                rhs[i] += row_a[i] * push
            for b in range(r, r + dim):
                weight = rows[a, ROW_HESSIAN + b - r]
                if weight == 0.0:
                    continue
                row_b, used_b = jac[b], columns[b, :counts[b]]
                for i in used_a:
                    scaled, target = weight * row_a[i], system[i]
                    for c in used_b:
                        target[c] += scaled * row_b[c]


@njit(cache=True, inline='always')
def _linear_force(rows, r, dim, a, column):
    """Row r + a's force by the cone's linearisation (`_linearise`) at the jar in
    rows[:, column]: ROW_LINEAR - H jar."""
    linear = rows[r + a, ROW_LINEAR]
    for b in range(dim):
        linear -= rows[r + a, ROW_HESSIAN + b] * rows[r + b, column]
    return linear


@njit(cache=True)
def _error(rows, r, dim, column, force, hessian):
    """Squared difference (N^2) of the cone's linearised force and MuJoCo's at the jar in
    rows[:, column], and the squared size of MuJoCo's; force[:dim] holds linearised minus
    MuJoCo's."""
    cone_force(rows, r, dim, cone_zone(rows, r, dim, column), column, force, hessian)
    error = size = 0.0
    for a in range(dim):
        size += force[a] ** 2
        force[a] = _linear_force(rows, r, dim, a, column) - force[a]
        error += force[a] ** 2
    return error, size


@njit(cache=True)
def cone_errors(constraints, qvel, solution, timestep):
    """After a solve: each cone's jar at the solution (ROW_JAR) and the force the solve gave it
    (ROW_FORCE: its linearisation's there). Returns the cones whose force there is off
    MuJoCo's by more than CONE_TOLERANCE."""
    rows, n = constraints[3], constraints[5]
    force, hessian = np.empty(CONE_ROWS), np.empty((CONE_ROWS, CONE_ROWS))
    wrong = 0
    for r in range(n):
        dim = _cone_dim(rows, r)
        if dim == 0:
            continue
        for a in range(r, r + dim):
            rows[a, ROW_JAR] = row_jar(constraints, a, qvel, solution, timestep)
        for a in range(dim):
            rows[r + a, ROW_FORCE] = _linear_force(rows, r, dim, a, ROW_JAR)
        error, size = _error(rows, r, dim, _JAR, force, hessian)
        wrong += error > CONE_TOLERANCE ** 2 * size
    return wrong


@njit(cache=True)
def cone_step(constraints, point, solution, system, rhs, timestep):
    """Newton's step of the cones from `point` (the end velocities they are linearised at)
    towards `solution` (the last solve's, of `system` x = `rhs`), damped: the first of
    alpha = 1, 1/2, ... (HALVINGS) where the squared residual of the whole system, the cones
    with MuJoCo's force, falls by Armijo's rule (else the last tried). With S x = b the
    system and f_lin the cones' linearised forces, the residual at v is
    S v - b + dt J^T (f_lin(v) - f(v)): at v = point + alpha (solution - point),
    (1 - alpha) (S point - b) + dt J^T (f_lin - f). The cones are linearised again at that
    v, which becomes `point`. Returns alpha."""
    jac, columns, counts, rows, n = (constraints[0], constraints[1], constraints[2],
                                      constraints[3], constraints[5])
    nv = point.shape[0]
    base, residual = np.empty(nv), np.empty(nv)
    force, hessian = np.empty(CONE_ROWS), np.empty((CONE_ROWS, CONE_ROWS))
    start = 0.0
    for i in range(nv):
        acc = -rhs[i]
        for j in range(nv):
            acc += system[i, j] * point[j]
        base[i] = acc
        start += acc * acc
    alpha = 1.0
    for halving in range(HALVINGS + 1):
        for i in range(nv):
            residual[i] = (1.0 - alpha) * base[i]
        for r in range(n):
            dim = _cone_dim(rows, r)
            if dim == 0:
                continue
            for a in range(r, r + dim):
                rows[a, ROW_TRIAL] = rows[a, ROW_POINT] + alpha * (rows[a, ROW_JAR]
                                                                   - rows[a, ROW_POINT])
            _error(rows, r, dim, _TRIAL, force, hessian)
            for a in range(dim):
                for c in columns[r + a, :counts[r + a]]:
                    residual[c] += timestep * jac[r + a, c] * force[a]
        squared = 0.0
        for i in range(nv):
            squared += residual[i] * residual[i]
        if squared <= (1.0 - 2.0 * ARMIJO * alpha) * start or halving == HALVINGS:
            break
        alpha *= 0.5
    _linearise_all(constraints, _TRIAL, timestep)
    for i in range(nv):
        point[i] += alpha * (solution[i] - point[i])
    return alpha


@njit(cache=True)
def cone_settled(constraints, timestep):
    """Where the cones' forces hold at the last solve's end velocities (`cone_errors`): each
    linearised there (ROW_POINT = ROW_JAR), for the solves the plates' and rows' sets may
    still ask for."""
    _linearise_all(constraints, _JAR, timestep)


@njit(cache=True)
def cone_reports(constraints):
    """After the last solve: the aref that makes MuJoCo report each cone row's force
    (ROW_REPORT: -jar at the solution; with the row's Jacobian zero MuJoCo sees that jar, and
    its force is its function of jar: the force applied, ROW_FORCE, where `cone_errors`
    found none off it)."""
    rows, n = constraints[3], constraints[5]
    for r in range(n):
        if rows[r, ROW_KIND] == CONE:
            rows[r, ROW_REPORT] = -rows[r, ROW_JAR]


forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
