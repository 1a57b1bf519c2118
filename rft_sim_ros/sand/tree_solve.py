"""The linear algebra of the implicit sand step on MuJoCo's kinematic tree, compiled: the
L^T D L factor of the step matrix (`tree_factor`, as mj_factorM), the slots' translational
inverse effective masses (`translational_inverse_masses`), and the solve of the step's
system (`checked_solve`: an elimination from the leaves that fills nothing in,
`tree_solve`, verified by its backward error, else a dense pivoted one).

Conventions: square nv x nv matrices with the sparsity of MuJoCo's joint-space inertia
(entry (i, j) nonzero only if one of dofs i, j is an ancestor of the other, as mj_fullM
gives); dof_parentid is mjModel's (-1 at a root). Work space is passed in: nothing here
allocates.
"""
from numba import njit

from ..kernel_cache import forget_stale


@njit(cache=True, error_model='numpy', fastmath=True)
def tree_factor(matrix, dof_parentid, factor):
    """L^T D L factor of an SPD joint-space matrix with the sparsity of MuJoCo's inertia (entry
    (i, j) nonzero only if one of dofs i, j is an ancestor of the other, as mj_fullM gives):
    MuJoCo's own factorisation (mj_factorM), eliminating from the leaves, which fills nothing
    in. Writes factor (nv, nv): D on the diagonal, the unit lower-triangular L below it
    (nonzero only at (dof, ancestor dof)), zero above. Rows are updated whole (zeros off the
    pattern stay zero), so the updates vectorise."""
    n = matrix.shape[0]
    for i in range(n):
        for j in range(n):
            factor[i, j] = matrix[i, j] if j <= i else 0.0
    for k in range(n - 1, -1, -1):
        inv = 1.0 / factor[k, k]
        row_k = factor[k]
        i = dof_parentid[k]
        while i >= 0:
            scale = row_k[i] * inv
            target, source = factor[i, :i + 1], row_k[:i + 1]
            for j in range(i + 1):
                target[j] -= source[j] * scale
            row_k[i] = scale
            i = dof_parentid[i]


@njit(cache=True, error_model='numpy', fastmath=True)
def translational_inverse_masses(mass_h, dof_parentid, jac, slots, factor, work, out):
    """out[s] = sum over the 3 translational rows J_r of slot s of J_r Mh^-1 J_r^T
    (1/kg) = |D^-1/2 L^-T J_r^T|^2 with Mh = L^T D L (`tree_factor`, into factor (nv, nv)),
    all 3S rows solved at once in work (nv, >= 3S) (their index innermost, so the loops
    vectorise)."""
    n, count = mass_h.shape[0], 3 * slots
    tree_factor(mass_h, dof_parentid, factor)
    for s in range(slots):
        for a in range(3):
            for i in range(n):
                work[i, 3 * s + a] = jac[6 * s + a, i]
    for i in range(n - 1, -1, -1):  # L^T z = J^T, from the leaves
        row = work[i]
        j = dof_parentid[i]
        while j >= 0:
            f = factor[i, j]
            target = work[j]
            for r in range(count):
                target[r] -= f * row[r]
            j = dof_parentid[j]
    out[:slots] = 0.0
    for i in range(n):  # |D^-1/2 z|^2, each dof's 1/D once
        inv = 1.0 / factor[i, i]
        row = work[i]
        for s in range(slots):
            x, y, z = row[3 * s], row[3 * s + 1], row[3 * s + 2]
            out[s] += (x * x + y * y + z * z) * inv

@njit(cache=True, error_model='numpy', fastmath=True)
def _solve(matrix, rhs):
    """Solve the dense square system matrix x = rhs (Gaussian elimination, partial pivoting).
    Overwrites both arguments; returns x."""
    n = rhs.shape[0]
    for col in range(n):
        pivot = col
        for row in range(col + 1, n):
            if abs(matrix[row, col]) > abs(matrix[pivot, col]):
                pivot = row
        if pivot != col:
            for c in range(n):
                matrix[col, c], matrix[pivot, c] = matrix[pivot, c], matrix[col, c]
            rhs[col], rhs[pivot] = rhs[pivot], rhs[col]
        inv = 1.0 / matrix[col, col]
        pivot_row = matrix[col]
        for row in range(col + 1, n):
            factor = matrix[row, col] * inv
            if factor != 0.0:  # whole rows (left of col: never read again), so it vectorises
                target = matrix[row]
                for c in range(n):
                    target[c] -= factor * pivot_row[c]
                rhs[row] -= factor * rhs[col]
    for row in range(n - 1, -1, -1):
        acc = rhs[row]
        for c in range(row + 1, n):
            acc -= matrix[row, c] * rhs[c]
        rhs[row] = acc / matrix[row, row]
    return rhs


#: Smallest pivot of the unpivoted `tree_solve`, relative to the largest entry of its row.
PIVOT = 1e-9
#: Largest componentwise backward error max_i |A x - b|_i / (|A| |x| + |b|)_i accepted from
#: `tree_solve` (a backward-stable solve gives about 1e-15).
BACKWARD_ERROR = 1e-10


@njit(cache=True, error_model='numpy', fastmath=True)
def tree_solve(matrix, rhs, dof_parentid):
    """Solve matrix x = rhs for a square matrix with the sparsity of MuJoCo's inertia (entry
    (i, j) nonzero only if one of dofs i, j is an ancestor of the other), by elimination from
    the leaves, without pivoting: eliminating dof k touches only the rows of its ancestors,
    at the columns of its ancestors, so nothing fills in. Overwrites both; returns True with
    x in rhs, or False (both left partly eliminated) at a pivot below PIVOT times the largest
    entry of its row, where the elimination would need pivoting. It can still lose accuracy
    to growth: `checked_solve` verifies its result. (Decided before any division: under
    fastmath the compiler may assume no inf or NaN arises, so they cannot be tested after.)"""
    n = rhs.shape[0]
    for k in range(n - 1, -1, -1):
        row = matrix[k]
        largest = 0.0
        for j in range(n):
            largest = max(largest, abs(row[j]))
        if not abs(row[k]) > PIVOT * largest:
            return False
        inv = 1.0 / row[k]
        row_k = row[:k]
        i = dof_parentid[k]
        while i >= 0:
            scale = matrix[i, k] * inv
            target = matrix[i, :k]
            for j in range(k):  # whole prefix (zeros off the ancestors stay zero): vectorises
                target[j] -= scale * row_k[j]
            rhs[i] -= scale * rhs[k]
            i = dof_parentid[i]
    for k in range(n):  # row k now holds its diagonal and its ancestors' columns only
        acc = rhs[k]
        row = matrix[k, :k]
        for j in range(k):
            acc -= row[j] * rhs[j]
        rhs[k] = acc / matrix[k, k]
    return True


@njit(cache=True, inline='always')
def copy_into(matrix, vector, matrix_out, vector_out):
    """matrix_out[:, :] = matrix and vector_out[:] = vector (same shapes), element by element:
    numpy's slice assignment compiles a shape check whose error message formatting took a
    quarter of the kernels' compile time."""
    for i in range(vector.shape[0]):
        vector_out[i] = vector[i]
        for j in range(matrix.shape[1]):
            matrix_out[i, j] = matrix[i, j]


@njit(cache=True, error_model='numpy')
def checked_solve(matrix, rhs, dof_parentid, factored, solution):
    """x of matrix x = rhs (matrix: tree sparsity as in `tree_solve`; left unchanged) into
    `solution` (factored: (n, n) work space): `tree_solve`, kept if it met no small pivot
    and its componentwise backward error is at most BACKWARD_ERROR, else the dense partially
    pivoted `_solve`. Returns solution."""
    copy_into(matrix, rhs, factored, solution)
    accurate = tree_solve(factored, solution, dof_parentid)
    if accurate:
        for i in range(rhs.shape[0]):
            residual, scale = -rhs[i], abs(rhs[i])
            for j in range(rhs.shape[0]):
                residual += matrix[i, j] * solution[j]
                scale += abs(matrix[i, j] * solution[j])
            accurate &= abs(residual) <= BACKWARD_ERROR * scale
    if not accurate:
        copy_into(matrix, rhs, factored, solution)
        _solve(factored, solution)
    return solution


forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
