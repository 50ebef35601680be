"""A fix to CasADi's generated eigen-clip convexification: QR steps on the right block.

``eigen-clip`` (codegen.py) diagonalises each block of the Lagrangian's Hessian: Householder
tridiagonalisation, then implicit symmetric QR steps with a Wilkinson shift
(``casadi_cvx_symm_schur``). Off-diagonals below ``tol (|d_i| + |d_i+1|)`` are set to zero, and each
step should act on the unreduced block just above the part already diagonal at the bottom (Golub
and Van Loan, Matrix Computations, algorithm 8.3.3). CasADi 3.8 instead steps on everything between
the leading and the trailing zeros: when a zero appears in the middle, the chase stops there, so the
block below it is never iterated while the one above is stepped with the shift of the one below.
The upper block then converges only linearly, at the ratio of its eigenvalues' distances to that
foreign shift; for two close eigenvalues (0.398988 and 0.398975 in the Hessian of the CC-EMPC's
terminal block, whose t_d and t_s columns are almost equal) this is ~1 - 3e-5 per step, and
``max_iter_eig`` = 1e5 steps run out: the SQP returns ``convexify_failed``. The same defect is
casadi/casadi issue 2973 (pull request 3177, not merged).

The patch replaces how the block is chosen, and nothing else: q counts the trailing diagonal part
as before, p is now the start of the unreduced block ending just above it. Every step is then an
ordinary Wilkinson step on an unreduced block, which converges cubically. The trace of rotations
(nn, p, offset per step) that ``casadi_cvx`` replays is written as before.
"""

from __future__ import annotations

import casadi as ca

CVX_BLOCK_CHOICE = """    p = 0;
    q = 0;
    sp = 0;
    sq = 0;
    for (i=0;i<n-1;++i) {
      if (t_off[n-i-2]==0 && sq==0) {
        q++;
      } else {
        sq = 1;
      }
      if (t_off[i]==0 && sp==0) {
        p++;
      } else {
        sp = 1;
      }
      if (q==n-1) {
        q = n;
        p = 0;
      }
    }
"""
"""CasADi's choice of the block to step on, in ``casadi_cvx_symm_schur`` (leading zeros for p)."""

CVX_BLOCK_CHOICE_FIXED = """    /* seaway (cvx_patch.py): the unreduced block above the trailing diagonal. */
    (void) sp;
    (void) sq;
    q = 0;
    while (q<n-1 && t_off[n-q-2]==0) q++;
    if (q==n-1) q = n;
    p = 0;
    if (q<n) {
      p = n-q-1;
      while (p>0 && t_off[p-1]!=0) p--;
    }
"""


def patch_cvx_block_choice(src: str) -> str:
    """Make the generated ``casadi_cvx_symm_schur`` step on the bottom unreduced block; fail loudly
    if CasADi changed the code's shape (and leave code without eigen-clip alone)."""
    if "casadi_cvx_symm_schur" not in src:
        return src
    if src.count(CVX_BLOCK_CHOICE) != 1:
        raise RuntimeError(
            "generated casadi_cvx_symm_schur has an unexpected shape (block choice not "
            f"found once); CasADi {ca.__version__} is not supported by cvx_patch"
        )
    return src.replace(CVX_BLOCK_CHOICE, CVX_BLOCK_CHOICE_FIXED)
