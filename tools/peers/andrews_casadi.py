#!/usr/bin/env python3
"""The CasADi peer of the work-precision report: Andrews' squeezing mechanism on SUNDIALS CVODES
(Adams and BDF) and IDAS as bundled in PyPI `casadi`, the model generated as C and compiled once.

    .venv-casadi/bin/python tools/peers/andrews_casadi.py [OUT.json] [--quick] [--reps N]

The model is written from the published equations (Hairer & Wanner, Solving ODEs II, VII.7; the
Bari IVP test set, problem "andrews"): M(q) q̈ = f(q, q̇) − Gᵀλ, g(q) = 0, with the test set's
constants, coordinates in its order (beta, theta, gamma, phi, delta, omega, epsilon). Forms:

- CVODES (Adams, BDF): the index-1 ODE x = (q, v), v̇ = q̈ from the KKT system
  [M Gᵀ; G 0] (q̈, λ) = (f, −γ), γ = ∂(G v)/∂q · v, with the constraint rows scaled by
  S = diag(1e-3) (G's entries are ~1e-2 m, M's ~1e-5 kg m²). Unscaled, CasADi's symbolic solve
  is exact at t = 0 (7e-15) but loses 7–8 digits of q̈ along the trajectory (1.5e-9 … 3.7e-8
  relative to an LU solve with pivoting at t = 0.005 … 0.03 s); scaled, 4e-16 … 2e-14.
- IDAS: the semi-explicit index-1 DAE x = (q, v), z = (q̈, λ): ẋ = (v, q̈),
  0 = (M q̈ + Gᵀλ − f, S(G q̈ + γ)), with per-variable absolute tolerances (see `idas_atol`).

Before any run the model is checked against the test set: q̈(0) and λ(0) (its consistent initial
values) to 1e-13 relative. The C code of the ODE and DAE right-hand sides and their Jacobians is
written by CasADi's code generator, compiled with gcc -O3 -fPIC -shared into a cache folder
(named by the SHA-256 of the source and flags: compiled once) and loaded with `casadi.external`,
as a CasADi user does. The integrators are built once per (solver, tolerance) and called 1 + reps
times; the CPU time of a run (process_cpu_s) is the least over the reps of the process CPU time
of one call (time.process_time, as the report measures the project's runs; cpu_s is the same by
wall clock, time.perf_counter); the compile and the integrator construction are outside it.
Evaluations are CasADi's SUNDIALS stats: right-hand-side (IDAS: residual) evaluations (nfevals),
and the Jacobian evaluations apart (n_call_jacF).

Output (stdout, or OUT.json): JSON with the versions, the model check, and one entry per run:
solver, rtol, atol, status ("ok" or the solver's error), cpu_s, process_cpu_s, nfevals, njevals,
nsteps and
q(0.03) in the test set's order. A run whose solver fails is recorded with its error.
"""

import hashlib
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time

import casadi as ca
import numpy as np

NAMES = ["beta", "theta", "gamma", "phi", "delta", "omega", "epsilon"]
T_END = 0.03

# Test set constants (andrews.f; Hairer & Wanner II, VII.7, Table 7.1).
m1, m2, m3, m4, m5, m6, m7 = 0.04325, 0.00365, 0.02373, 0.00706, 0.07050, 0.00706, 0.05498
i1, i2, i3, i4, i5, i6, i7 = 2.194e-6, 4.410e-7, 5.255e-6, 5.667e-7, 1.169e-5, 5.667e-7, 1.912e-5
xa, ya, xb, yb, xc, yc = -0.06934, -0.00227, -0.03635, 0.03273, 0.014, 0.072
d, da, e, ea, rr, ra = 28e-3, 115e-4, 2e-2, 1421e-5, 7e-3, 92e-5
ss, sa, sb, sc, sd = 35e-3, 1874e-5, 1043e-5, 18e-3, 2e-2
ta, tb, u, ua, ub = 2308e-5, 916e-5, 4e-2, 1228e-5, 449e-5
zf, zt, fa, mom, c0, lo = 2e-2, 4e-2, 1421e-5, 0.033, 4530.0, 0.07785

# The test set's consistent initial values (to 30 digits there; f64 here): q(0), q̇(0) = 0,
# q̈(0) and λ(0).
Q0 = [
    -0.0617138900142764496358948458001,
    0.0,
    0.455279819163070380255912382449,
    0.222668390165885884674473185609,
    0.487364979543842550225598953530,
    -0.222668390165885884674473185609,
    1.23054744454982119249735015568,
]
QDD0 = [14222.4439199541138705911625887, -10666.8329399655854029433719415, 0, 0, 0, 0, 0]
LAMBDA0 = [98.5668703962410896057654982170, -6.12268834425566265503114393122, 0, 0, 0, 0]
# The test set's reference q(0.03) (PSIDE, tol 1e-14; itself accurate to ~1.4e-9 rad).
Q_REF = [
    0.1581077119629904e02,
    -0.1575637105984298e02,
    0.4082224013073101e-01,
    -0.5347301163226948e00,
    0.5244099658805304e00,
    0.5347301163226948e00,
    0.1048080741042263e01,
]

# Constraint-row scale of the KKT system and of the DAE's constraint residual.
ROW_SCALE = 1e-3


def model(q, v):
    """M(q), f(q, v), G(q) = ∂g/∂q and g(q) of the test set."""
    be, th, ga, ph, de, om, ep = [q[k] for k in range(7)]
    bep, thp, _, php, dep, omp, epp = [v[k] for k in range(7)]
    sibe, sith, siga, siph, side, siom, siep = [ca.sin(a) for a in (be, th, ga, ph, de, om, ep)]
    cobe, coth, coga, coph, code, coom, coep = [ca.cos(a) for a in (be, th, ga, ph, de, om, ep)]
    sibeth, cobeth = ca.sin(be + th), ca.cos(be + th)
    siphde, cophde = ca.sin(ph + de), ca.cos(ph + de)
    siomep, coomep = ca.sin(om + ep), ca.cos(om + ep)

    M = ca.SX.zeros(7, 7)
    M[0, 0] = m1 * ra**2 + m2 * (rr**2 - 2 * da * rr * coth + da**2) + i1 + i2
    M[1, 0] = M[0, 1] = m2 * (da**2 - da * rr * coth) + i2
    M[1, 1] = m2 * da**2 + i2
    M[2, 2] = m3 * (sa**2 + sb**2) + i3
    M[3, 3] = m4 * (e - ea) ** 2 + i4
    M[4, 3] = M[3, 4] = m4 * ((e - ea) ** 2 + zt * (e - ea) * siph) + i4
    M[4, 4] = m4 * (zt**2 + 2 * zt * (e - ea) * siph + (e - ea) ** 2) + m5 * (ta**2 + tb**2) + i4 + i5
    M[5, 5] = m6 * (zf - fa) ** 2 + i6
    M[6, 5] = M[5, 6] = m6 * ((zf - fa) ** 2 - u * (zf - fa) * siom) + i6
    M[6, 6] = m6 * ((zf - fa) ** 2 - 2 * u * (zf - fa) * siom + u**2) + m7 * (ua**2 + ub**2) + i6 + i7

    xd = sd * coga + sc * siga + xb
    yd = sd * siga - sc * coga + yb
    lang = ca.sqrt((xd - xc) ** 2 + (yd - yc) ** 2)
    force = -c0 * (lang - lo) / lang
    fx, fy = force * (xd - xc), force * (yd - yc)
    f = ca.vertcat(
        mom - m2 * da * rr * thp * (thp + 2 * bep) * sith,
        m2 * da * rr * bep**2 * sith,
        fx * (sc * coga - sd * siga) + fy * (sd * coga + sc * siga),
        m4 * zt * (e - ea) * dep**2 * coph,
        -m4 * zt * (e - ea) * php * (php + 2 * dep) * coph,
        -m6 * u * (zf - fa) * epp**2 * coom,
        m6 * u * (zf - fa) * omp * (omp + 2 * epp) * coom,
    )
    g = ca.vertcat(
        rr * cobe - d * cobeth - ss * siga - xb,
        rr * sibe - d * sibeth + ss * coga - yb,
        rr * cobe - d * cobeth - e * siphde - zt * code - xa,
        rr * sibe - d * sibeth + e * cophde - zt * side - ya,
        rr * cobe - d * cobeth - zf * coomep - u * siep - xa,
        rr * sibe - d * sibeth - zf * siomep + u * coep - ya,
    )
    G = ca.jacobian(g, q)
    return M, f, G, g


def dyn(name, x, z, ode, alg):
    """A Function with CasADi's DAE inputs (t, x, z, p, u) and outputs (ode, alg, quad, zero)."""
    t, empty = ca.SX.sym("t"), ca.SX(0, 1)
    return ca.Function(
        name,
        [t, x, z, ca.SX.sym("p", 0), ca.SX.sym("u", 0)],
        [ode, alg, empty, empty],
        ca.dyn_in(),
        ca.dyn_out(),
    )


def functions():
    """The ODE (for CVODES), the DAE (for IDAS) and the KKT solve at a state (for the checks)."""
    q, v = ca.SX.sym("q", 7), ca.SX.sym("v", 7)
    M, f, G, g = model(q, v)
    gamma = ca.jtimes(ca.mtimes(G, v), q, v)  # (∂(G v)/∂q) v: q̈-independent part of g̈
    S = ROW_SCALE
    kkt = ca.blockcat([[M, S * G.T], [S * G, ca.SX.zeros(6, 6)]])
    sol = ca.solve(kkt, ca.vertcat(f, -S * gamma))
    qdd, lam = sol[:7], S * sol[7:]
    x = ca.vertcat(q, v)
    ode = dyn("andrews_ode", x, ca.SX(0, 1), ca.vertcat(v, qdd), ca.SX(0, 1))
    w, lz = ca.SX.sym("w", 7), ca.SX.sym("lambda", 6)
    z = ca.vertcat(w, lz)
    # Dynamic rows in units of q̈ (divided by the mass scale 1e-5), constraint rows scaled.
    alg = ca.vertcat((ca.mtimes(M, w) + ca.mtimes(G.T, lz) - f) * 1e5, S * 1e3 * (ca.mtimes(G, w) + gamma))
    dae = dyn("andrews_dae", x, z, ca.vertcat(v, w), alg)
    kkt_fun = ca.Function("andrews_kkt", [x], [qdd, lam, g])
    return ode, dae, kkt_fun


def compile_c(funcs, cache):
    """Generate one C file with `funcs` and their Jacobians, compile it once into `cache` (named
    by the SHA-256 of the source and flags), return the shared library's path and whether it was
    built now, and the compile time."""
    cc = os.environ.get("CC", "gcc")
    flags = ["-O3", "-fPIC", "-shared"]
    os.makedirs(cache, exist_ok=True)
    gen_dir = tempfile.mkdtemp(dir=cache)
    cg = ca.CodeGenerator("andrews_peer.c", {"with_header": False})
    for fn in funcs:
        cg.add(fn)
        cg.add(fn.jacobian())
    try:
        cg.generate(gen_dir + os.sep)
        src = open(os.path.join(gen_dir, "andrews_peer.c"), "rb").read()
    finally:
        shutil.rmtree(gen_dir)
    key = hashlib.sha256(src + " ".join([cc] + flags).encode()).hexdigest()[:16]
    so = os.path.join(cache, f"andrews_{key}.so")
    built, seconds = False, 0.0
    if not os.path.exists(so):
        c_file = os.path.join(cache, f"andrews_{key}.c")
        with open(c_file, "wb") as fh:
            fh.write(src)
        start = time.perf_counter()
        part = f"{so}.{os.getpid()}"
        subprocess.run([cc, *flags, c_file, "-o", part, "-lm"], check=True)
        os.replace(part, so)
        seconds = time.perf_counter() - start
        built = True
    return so, built, seconds


def check_model(kkt_fun):
    """q̈(0), λ(0) against the test set's consistent initial values; g(q0) = 0."""
    x0 = np.array(Q0 + [0.0] * 7)
    qdd, lam, g = [np.array(a).ravel() for a in kkt_fun(x0)]
    qdd_rel = float(np.max(np.abs(qdd - QDD0)) / np.max(np.abs(QDD0)))
    lam_rel = float(np.max(np.abs(lam - LAMBDA0)) / np.max(np.abs(LAMBDA0)))
    out = {
        "qdd0": qdd.tolist(),
        "lambda0": lam.tolist(),
        "qdd0_max_rel_error": qdd_rel,
        "lambda0_max_rel_error": lam_rel,
        "g0_max_abs": float(np.max(np.abs(g))),
    }
    if not (qdd_rel <= 1e-13 and lam_rel <= 1e-13 and out["g0_max_abs"] <= 1e-15):
        raise SystemExit(f"andrews_casadi: the model does not match the test set at t = 0: {out}")
    return out, qdd, lam


def idas_atol(tol):
    """IDAS's absolute tolerances per variable: q and v at `tol`; the algebraic q̈ (~1e4 rad/s²)
    and λ (~1e2 N) at tol × their scale, never below 1e-10 × it. Measured here: atol = tol on
    every variable fails at tol = 1e-13 (IDA_CONV_FAIL, the corrector at t ≈ 1e-16), as does
    suppressing the algebraic variables from the error test; scaled without the floor, IDAS needs
    2.8× the residual evaluations at 1e-13 for the same error."""
    za = max(tol, 1e-10)
    return [tol] * 14 + [za * 1e4] * 7 + [za * 1e2] * 6


def run(integrator, args, reps):
    """Call `integrator` 1 + reps times; the least wall-clock and the least process CPU time of
    one call over the reps, the stats and q(0.03) of the last call."""
    res = integrator(**args)
    wall, cpu = float("inf"), float("inf")
    for _ in range(reps):
        w0, c0 = time.perf_counter(), time.process_time()
        res = integrator(**args)
        wall = min(wall, time.perf_counter() - w0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu, integrator.stats(), np.array(res["xf"]).ravel()[:7]


def main():
    argv = sys.argv[1:]
    quick = "--quick" in argv
    reps = 5
    if "--reps" in argv:
        reps = int(argv[argv.index("--reps") + 1])
    paths = [a for a in argv if a.endswith(".json")]
    here = os.path.dirname(os.path.abspath(__file__))
    repo = os.path.abspath(os.path.join(here, "..", ".."))
    cache = os.environ.get("CD_CASADI_CACHE", os.path.join(repo, "target", "casadi-peer"))

    ode_sx, dae_sx, kkt_fun = functions()
    check, qdd0, lam0 = check_model(kkt_fun)
    so, built, compile_s = compile_c([ode_sx, dae_sx], cache)
    ode = ca.external("andrews_ode", so)
    dae = ca.external("andrews_dae", so)
    # The compiled functions against the symbolic ones at the initial state.
    x0 = np.array(Q0 + [0.0] * 7)
    gap = float(np.max(np.abs(np.array(ode(x=x0)["ode"]) - np.array(ode_sx(x=x0)["ode"]))))
    assert gap <= 1e-9, f"compiled ODE differs from the symbolic one by {gap}"

    tols = [1e-4, 1e-7, 1e-10] if quick else [10.0**-k for k in range(4, 14)]
    runs = []
    z0 = np.concatenate([qdd0, lam0])
    for solver in ["cvodes_adams", "cvodes_bdf", "idas"]:
        for tol in tols:
            opts = {"reltol": tol, "abstol": tol, "max_num_steps": 10**7}
            if solver.startswith("cvodes"):
                opts["linear_multistep_method"] = "adams" if solver == "cvodes_adams" else "bdf"
                integ = ca.integrator(f"I_{solver}", "cvodes", ode, 0.0, T_END, opts)
                args = {"x0": x0}
            else:
                opts["abstolv"] = idas_atol(tol)
                integ = ca.integrator("I_idas", "idas", dae, 0.0, T_END, opts)
                args = {"x0": x0, "z0": z0}
            entry = {"solver": solver, "rtol": tol, "atol": tol}
            if solver == "idas":
                entry["atol_algebraic"] = {"qdd": idas_atol(tol)[14], "lambda": idas_atol(tol)[21]}
            try:
                wall, cpu, stats, q = run(integ, args, reps)
                entry.update(
                    status="ok",
                    cpu_s=wall,
                    process_cpu_s=cpu,
                    nfevals=int(stats.get("nfevals", -1)),
                    njevals=int(stats.get("n_call_jacF", -1)),
                    nsteps=int(stats.get("nsteps", -1)),
                    q=q.tolist(),
                    max_abs_diff_to_test_set=float(np.max(np.abs(q - np.array(Q_REF)))),
                )
            except RuntimeError as err:
                entry.update(status=" ".join(str(err).split())[:300])
            runs.append(entry)
            print(
                f"andrews_casadi: {solver} tol {tol:.0e}: {entry['status'][:80]}"
                + (f", {entry['cpu_s'] * 1e3:.2f} ms, {entry['nfevals']} evaluations" if entry["status"] == "ok" else ""),
                file=sys.stderr,
            )

    out = {
        "peer": "casadi",
        "casadi": ca.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
        "compiler": subprocess.run(
            [os.environ.get("CC", "gcc"), "--version"], capture_output=True, text=True
        ).stdout.splitlines()[0],
        "shared_library": so,
        "compiled_now": built,
        "compile_s": compile_s,
        "names": NAMES,
        "t_end": T_END,
        "cpu": f"process CPU time (time.process_time, process_cpu_s; the report's measure) of one "
        f"integrator call, the least of {reps} after a warm-up call; cpu_s: the same by wall clock",
        "model_check": check,
        "runs": runs,
    }
    text = json.dumps(out, indent=1)
    if paths:
        with open(paths[0], "w") as fh:
            fh.write(text + "\n")
    else:
        print(text)


if __name__ == "__main__":
    main()
