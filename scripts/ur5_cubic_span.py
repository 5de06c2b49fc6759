#!/usr/bin/env python3
"""How much of the UR5's needed cubic spring term do a catalogue's coupling directions span?

springfit fits springs so that U = U_springs + U_gravity equals U* = ½ω²r(q)² near q_eq, r the
metric geodesic distance from q_eq. The springs must therefore supply U_s = ½ω²r² − U_g. With the
equilibrium and the Hessian matched exactly (the fit holds them as equalities), the first error
near q_eq is the cubic Taylor term of U_s. A spring on x = a·q with profile u contributes
k u'''(a·q_eq − x0) (a·δ)³ / 6 to it: only the cube a⊗a⊗a of its coupling direction. Cranks
(u''' = −sin(x − x0), twelve phases) give either sign, so the question is whether the symmetric
third-derivative tensor T of U_s lies in the *linear* span of {a⊗a⊗a}.

Derivation of the metric term. Let δ = q − q_eq, v = log_{q_eq}(q). exp(v) = q_eq + v − ½Γ(v,v) + O(3),
so v = δ + ½Γ(δ,δ) + O(3) and r² = M(v,v) = M(δ,δ) + Γ_{i,kl} δ^i δ^k δ^l + O(4), where
Γ_{i,kl} = ½(∂_k M_il + ∂_l M_ik − ∂_i M_kl); contracted with δδδ that is ½ ∂_k M_ij δ^i δ^j δ^k. So
  ½ω²r² = ½ω² M(δ,δ) + ¼ω² Σ ∂_k M_ij δ^i δ^j δ^k + O(δ⁴),
i.e. third derivative T_r = (3/2) ω² Sym(∂_k M_ij). `check_expansion()` verifies this by shooting
geodesics numerically (the remainder must fall as ε⁴). Gravity: T_g = ∂²g/∂q², g = ∂U_g/∂q the
generalized gravity (finite differences of Pinocchio's analytic dg/dq). T = T_r − T_g.

Norms. "joint" = Frobenius norm of T_ijk in joint coordinates (rad). "metric" = the same tensor
in metric-orthonormal coordinates δ = L^{-T} u (M(q_eq) = L Lᵀ), which weighs directions as the
fit's geodesic ball does (the wrist joints move by radians, the shoulder by a tenth). Residual
fractions are ‖T − Σ c_a a⊗a⊗a‖ / ‖T‖ with c from unconstrained least squares in that norm.

Run: python3 scripts/ur5_cubic_span.py [--check] [--residual]   (needs `pip install pin`)
  --check     shoot geodesics and confirm the cubic term (remainder falls 16× per halving of ε)
  --residual  list what each set leaves unspanned, and the angle slope it predicts near q_eq

What it found (ω = 6, q_eq = (0, −π/4, π/2, −π/2, π/2, 0)): Pinocchio's M(q_eq) equals the one
`springfit check` prints. Gravity's cubic term is spanned exactly by chain.toml (U_g is a sum of
functions of q2, q2+q3, q2+q3+q4); the metric's is not: chain.toml's 52 crank directions span a
40-dimensional space and leave 12 % of T (joint norm; 28 % in metric coordinates), all of it
q1·q5·(q2+q3+q4) and q1·q6·(q2+q3+q4). Adding the 64 non-adjacent triples (ii) spans everything;
the eight directions q1 ± (q2+q3+q4) ± q5, q1 ± (q2+q3+q4) ± q6 (iii, catalogs/ur5_span.toml)
leave 0.0 % (0.4 % metric).
"""
import itertools
import os
import sys

import numpy as np
import pinocchio as pin

HERE = os.path.dirname(os.path.abspath(__file__))
URDF = os.path.join(HERE, "..", "robots", "ur5", "ur5_robot.urdf")
JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
          "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
Q_EQ = np.array([0.0, -np.pi / 4, np.pi / 2, -np.pi / 2, np.pi / 2, 0.0])
OMEGA = 6.0
N = 6

# --- the robot -------------------------------------------------------------------------------
model = pin.buildModelFromUrdf(URDF)
assert [model.names[i] for i in range(1, model.njoints)] == JOINTS, list(model.names)
model.gravity.linear = np.array([0.0, 0.0, -9.81])
data = model.createData()


def mass(q):
    M = pin.crba(model, data, q)
    return np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle only


def grav(q):
    return pin.computeGeneralizedGravity(model, data, q).copy()


def dgrav(q):
    return pin.computeGeneralizedGravityDerivatives(model, data, q).copy()


def dmass(q, h=1e-5):
    """dM[k, i, j] = ∂_k M_ij by central differences."""
    out = np.zeros((N, N, N))
    for k in range(N):
        e = np.zeros(N); e[k] = h
        out[k] = (mass(q + e) - mass(q - e)) / (2 * h)
    return out


def sym3(t):
    return sum(np.transpose(t, p) for p in itertools.permutations(range(3))) / 6.0


def third_derivative_tensors(q):
    dM = dmass(q)
    T_r = 1.5 * OMEGA**2 * sym3(dM)           # ½ω²r²: cubic term ¼ω² ∂_k M_ij δδδ = T/6 δδδ
    h = 1e-5
    T_g = np.zeros((N, N, N))                   # T_g[k, i, j] = ∂_k ∂_j g_i
    for k in range(N):
        e = np.zeros(N); e[k] = h
        T_g[k] = (dgrav(q + e) - dgrav(q - e)) / (2 * h)
    T_g = sym3(T_g)                             # symmetric up to FD error already
    return T_r, T_g


# --- a numerical check of the expansion: shoot geodesics ------------------------------------
def christoffel(q):
    dM = dmass(q, 1e-6)
    # Γ_{i,kl} = ½(∂_k M_il + ∂_l M_ik − ∂_i M_kl)
    G1 = 0.5 * (np.einsum("kil->ikl", dM) + np.einsum("lik->ikl", dM) - dM)
    return np.linalg.solve(mass(q), G1.reshape(N, -1)).reshape(N, N, N)


def shoot(q0, v, steps=200):
    """RK4 on q'' = −Γ(q', q') for unit time."""
    def f(y):
        q, w = y[:N], y[N:]
        return np.concatenate([w, -np.einsum("ikl,k,l->i", christoffel(q), w, w)])
    y = np.concatenate([q0, v]); dt = 1.0 / steps
    for _ in range(steps):
        k1 = f(y); k2 = f(y + dt / 2 * k1); k3 = f(y + dt / 2 * k2); k4 = f(y + dt * k3)
        y = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return y[:N]


def check_expansion(T_r):
    rng = np.random.default_rng(0)
    M0 = mass(Q_EQ)
    print("expansion check: ½ω²r² − [½ω²M(δ,δ) + T_r(δ,δ,δ)/6] should fall as ε⁴ (as ε³ without the cubic term)")
    for _ in range(2):
        u = rng.normal(size=N); u /= np.sqrt(u @ M0 @ u)
        for eps in (0.1, 0.05, 0.025):
            v = eps * u
            d = shoot(Q_EQ, v, steps=40) - Q_EQ
            exact = 0.5 * OMEGA**2 * (v @ M0 @ v)          # r = |v|_M for unit time
            quad = 0.5 * OMEGA**2 * (d @ M0 @ d)
            cub = np.einsum("ijk,i,j,k", T_r, d, d, d) / 6
            print(f"  ε={eps:<6} without cubic {exact - quad:+.3e}   with cubic {exact - quad - cub:+.3e}")


# --- spans --------------------------------------------------------------------------------------
def cube(a):
    a = np.asarray(a, float)
    return np.einsum("i,j,k->ijk", a, a, a)


def residual_fraction(T, dirs, W=None):
    """Relative Frobenius residual of least-squares T ≈ Σ c_a a⊗a⊗a (signed c)."""
    if W is not None:  # metric coordinates u = Lᵀδ: T'_ijk = W_ia W_jb W_kc T_abc and a' = W a, W = L⁻¹
        T = np.einsum("ia,jb,kc,abc->ijk", W, W, W, T)
        dirs = [W @ np.asarray(a, float) for a in dirs]
    A = np.stack([cube(a).ravel() for a in dirs], axis=1)
    b = T.ravel()
    c, *_ = np.linalg.lstsq(A, b, rcond=None)
    return np.linalg.norm(A @ c - b) / np.linalg.norm(b), np.linalg.matrix_rank(A, tol=1e-9 * np.abs(A).max())


def canon(a):
    a = tuple(int(x) for x in a)
    first = next(x for x in a if x != 0)
    return a if first > 0 else tuple(-x for x in a)


def chain_dirs():
    """The crank couplings of catalogs/chain.toml: joints, all pairs (1,±1), adjacent triples."""
    d = set()
    for i in range(N):
        e = [0] * N; e[i] = 1; d.add(canon(e))
    for i, j in itertools.combinations(range(N), 2):
        for r in ((1, 1), (1, -1)):
            e = [0] * N; e[i], e[j] = r; d.add(canon(e))
    for i in range(N - 2):
        for r in ((1, 1, 1), (1, -1, 1), (1, 1, -1), (1, -1, -1)):
            e = [0] * N; e[i:i + 3] = r; d.add(canon(e))
    return sorted(d)


def all_triples_dirs():
    d = set()
    for i, j, k in itertools.combinations(range(N), 3):
        for r in ((1, 1, 1), (1, -1, 1), (1, 1, -1), (1, -1, -1)):
            e = [0] * N; e[i], e[j], e[k] = r; d.add(canon(e))
    return sorted(d)


def monomials(T):
    """Coefficients of the cubic polynomial T(δ,δ,δ)/6 by monomial δ_i δ_j δ_k (i ≤ j ≤ k)."""
    out = {}
    for idx in itertools.combinations_with_replacement(range(N), 3):
        mult = len(set(itertools.permutations(idx)))
        out[idx] = T[idx] * mult / 6.0
    return out


def mono_r(T, idx):
    """One monomial's coefficient in T(δ,δ,δ)/6."""
    mult = len(set(itertools.permutations(idx)))
    return T[idx] * mult / 6.0


def main():
    M0 = mass(Q_EQ)
    np.set_printoptions(precision=4, suppress=True, linewidth=140)
    print("M(q_eq) (Pinocchio):\n", M0)
    T_r, T_g = third_derivative_tensors(Q_EQ)
    T = T_r - T_g
    if "--check" in sys.argv:
        check_expansion(T_r)

    L = np.linalg.cholesky(M0)            # M = L Lᵀ; metric coords u = Lᵀ δ, so a·δ = (L⁻¹a)·u
    Wm = np.linalg.inv(L)                 # both T's indices and the directions transform by L⁻¹

    print(f"\n‖T_r‖ = {np.linalg.norm(T_r):.3f}, ‖T_g‖ = {np.linalg.norm(T_g):.3f}, "
          f"‖T_s = T_r − T_g‖ = {np.linalg.norm(T):.3f} (joint coords, N·m/rad²)")
    names = ["q1", "q2", "q3", "q4", "q5", "q6"]
    mono = monomials(T)
    big = max(abs(v) for v in mono.values())
    print("\nsignificant monomials of the cubic term T_s(δ,δ,δ)/6 (relative to the largest, ≥ 2 %):")
    for idx, v in sorted(mono.items(), key=lambda kv: -abs(kv[1])):
        if abs(v) >= 0.02 * big:
            print(f"  {'·'.join(names[i] for i in idx):<12} {v:+9.4f}  ({abs(v) / big:5.1%})"
                  f"   [metric {mono_r(T_r, idx):+.3f}, gravity {-mono_r(T_g, idx):+.3f}]")

    sets = {}
    sets["(i) chain.toml"] = chain_dirs()
    sets["(ii) chain + all 20 triples × 4 signs"] = sorted(set(chain_dirs()) | set(all_triples_dirs()))
    # (iii) What the residual of (i) is made of (run with --residual): almost only
    # q1·q5·(q2+q3+q4) and q1·q6·(q2+q3+q4), the inertia coupling of the pan with wrists 2 and 3
    # through the wrist-1 link's absolute pitch s = q2+q3+q4. A product u·v·w of three linear forms
    # is (1/24) Σ± of the cubes of u ± v ± w, so four directions q1 ± s ± q5 (and four with q6) span it.
    s_ = np.array([0, 1, 1, 1, 0, 0])
    e = np.eye(N, dtype=int)
    extra_s = [e[0] + p * s_ + m * e[k] for k in (4, 5) for p in (1, -1) for m in (1, -1)]
    # The same products written out joint by joint: triples (q1, qk, q5) and (q1, qk, q6), k = 2, 3, 4,
    # with the four sign patterns of chain.toml's triples (non-adjacent, so explicit vectors).
    extra_t = [r[0] * e[0] + r[1] * e[k] + r[2] * e[l] for k in (1, 2, 3) for l in (4, 5)
               for r in ((1, 1, 1), (1, -1, 1), (1, 1, -1), (1, -1, -1))]
    sets["(iii) chain + q1±(q2+q3+q4)±q5, q1±(q2+q3+q4)±q6"] = sorted(set(chain_dirs()) | {canon(a) for a in extra_s})
    sets["(iii-b) chain + triples (q1,qk,q5), (q1,qk,q6), k=2..4"] = sorted(set(chain_dirs()) | {canon(a) for a in extra_t})
    sets["(iii-c) chain + q2+q3+q4±q5, q3+q4±q5, q2+q3±q5"] = sorted(set(chain_dirs()) | {canon(a) for a in [
        (0, 1, 1, 1, 1, 0), (0, 1, 1, 1, -1, 0), (0, 0, 1, 1, 1, 0), (0, 0, 1, 1, -1, 0),
        (0, 1, 1, 0, 1, 0), (0, 1, 1, 0, -1, 0)]})

    print("\nresidual fraction of T_s outside span{a⊗a⊗a}  (rank = dimension spanned; cubics in 6 variables: 56):")
    for name, dirs in sets.items():
        fj, rk = residual_fraction(T, dirs)
        fm, _ = residual_fraction(T, dirs, Wm)
        print(f"  {name:<52} {len(dirs):4d} dirs, rank {rk:2d}: joint {fj:6.1%}, metric {fm:6.1%}")
    if "--residual" in sys.argv:
        for name in ("(i) chain.toml", "(iii) chain + q1±(q2+q3+q4)±q5, q1±(q2+q3+q4)±q6"):
            dirs = sets[name]
            A = np.stack([cube(a).ravel() for a in dirs], axis=1)
            c, *_ = np.linalg.lstsq(A, T.ravel(), rcond=None)
            R = (T.ravel() - A @ c).reshape(T.shape)
            print(f"\nlargest monomials of the residual of {name} (joint coords):")
            for idx, v in sorted(monomials(R).items(), key=lambda kv: -abs(kv[1]))[:8]:
                print(f"  {'·'.join(names[i] for i in idx):<12} {v:+9.4f}")
        # As an angle: the cubic residual R gives a gradient error ½R(δ,δ,·) against ω²Mδ, so the
        # angle grows as s·|½R(û,û,·)|_{M⁻¹}/ω² on metric unit directions û; sampled here.
        rng = np.random.default_rng(1)
        Linv = np.linalg.inv(L)
        for name, dirs in sets.items():
            A = np.stack([cube(a).ravel() for a in dirs], axis=1)
            c, *_ = np.linalg.lstsq(A, T.ravel(), rcond=None)
            R = (T.ravel() - A @ c).reshape(T.shape)
            ang = []
            for _ in range(4000):
                uu = rng.normal(size=N); uu /= np.linalg.norm(uu)
                d = Linv.T @ uu                      # metric unit: dᵀ M d = 1
                gerr = 0.5 * np.einsum("ijk,j,k->i", R, d, d)
                ang.append(np.sqrt(gerr @ np.linalg.solve(M0, gerr)) / OMEGA**2)
            print(f"  {name:<52} predicted p99 angle/s from the cubic residual: {np.degrees(np.percentile(ang, 99)):.2f}°/unit s")
    return T, T_r, T_g, sets, Wm



if __name__ == "__main__":
    main()
