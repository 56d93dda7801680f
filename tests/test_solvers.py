"""Solvers: the numba kernel against NumPy, thread-count independence, conservation, maximum
principle, agreement between explicit / implicit / steady and with exact solutions, the
stability bound, floating clusters and rattlers, the energy ledger, checkpoint/resume.

Problems are built directly with numpy on simple-cubic lattices with seeded random
conductances and capacities (no packing file, no law)."""
import numba
import numpy as np
import pytest
import scipy.linalg

from thermal_kernel.lattice import simple_cubic_packing
from thermal_kernel.network import NetworkError, assemble, make_problem, tied_clusters
from thermal_kernel.solvers import (UnstableTimeStepError, run_explicit, run_implicit,
                                    solve_steady)
from thermal_kernel.solvers.explicit import explicit_step, explicit_step_reference

# `make coverage` counts this module (marker kernel: its subject is thermal_kernel, and it is
# fast enough with NUMBA_DISABLE_JIT=1)
pytestmark = pytest.mark.kernel


def lattice(shape, seed=0, h=(0.5, 2.0), c=(1.0, 3.0)):
    pk = simple_cubic_packing(shape, 1e-3)
    rng = np.random.default_rng(seed)
    n, m = pk.position.shape[0], pk.pair.shape[0]
    return pk, rng.uniform(*h, m), rng.uniform(*c, n), rng


def faces(pk, axis=0):
    x = pk.position[:, axis]
    return np.flatnonzero(x == x.min()), np.flatnonzero(x == x.max())


def two_face_problem(shape=(6, 5, 4), seed=0, t_cold=300.0, t_hot=400.0, **kw):
    pk, h, c, rng = lattice(shape, seed)
    lo, hi = faces(pk)
    fixed = (np.r_[lo, hi], np.r_[np.full(lo.size, t_cold), np.full(hi.size, t_hot)],
             np.r_[np.zeros(lo.size), np.ones(hi.size)])
    return make_problem(c, pk.pair, h, fixed=fixed, boundary_names=("cold", "hot"), **kw), pk


class Pulse:
    """A source that switches on over [0.5, 1.5] s on a few particles (one of them held)."""

    def __init__(self, n, where):
        self.n, self.where = n, np.asarray(where)

    def __call__(self, t0, t1):
        out = np.zeros(self.n)
        on = max(0.0, min(t1, 1.5) - max(t0, 0.5))
        if t1 > t0:
            out[self.where] = 3.0 * on / (t1 - t0)
        elif 0.5 <= t0 <= 1.5:
            out[self.where] = 3.0
        return out


def everything_problem(seed=3):
    """Dirichlet face, exchange (one row on a held particle, one particle with two rows),
    power (one row on a held particle) and a time-dependent source (one particle held)."""
    pk, h, c, rng = lattice((5, 4, 4), seed)
    n = c.size
    lo, hi = faces(pk)
    ex_p = np.r_[hi, hi[0], lo[0]]
    ex = (ex_p, rng.uniform(0.2, 1.0, ex_p.size), np.full(ex_p.size, 350.0),
          np.full(ex_p.size, 1))
    pw_p = np.array([40, 41, lo[1]])
    power = (pw_p, np.array([0.7, -0.2, 0.4]), np.array([2, 2, 2]))
    src = Pulse(n, [20, 21, lo[2]])
    prob = make_problem(c, pk.pair, h, fixed=(lo, np.full(lo.size, 300.0),
                                              np.zeros(lo.size)),
                        exchange=ex, power=power, source=src, source_boundary=3,
                        boundary_names=("cold", "wall", "heater", "source"))
    return prob, pk


# ---------------------------------------------------------------- kernel vs numpy reference
def test_numba_kernel_equals_numpy_reference():
    prob, _ = everything_problem()
    net = assemble(prob)
    rng = np.random.default_rng(7)
    T = 300.0 + 50.0 * rng.random(net.n)
    T[net.held] = net.held_temperature_k[net.held]
    sw = rng.random(net.n)
    dt = 0.8 * net.dt_max_s
    for s in (None, sw):
        got = explicit_step(net, T, dt, s)
        ref = explicit_step_reference(net, T, dt, s)
        np.testing.assert_allclose(got - T, ref - T, rtol=1e-12, atol=1e-12 * 50)
        assert np.array_equal(got[net.held], T[net.held])


def test_bit_identical_with_1_and_2_threads_and_across_runs():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has fewer than 2 threads on this machine")
    prob, _ = two_face_problem((20, 20, 20), seed=1)
    net = assemble(prob)
    T0 = 300.0 + 100.0 * np.random.default_rng(2).random(net.n)
    runs = [run_explicit(net, T0, [0.5, 1.0], threads=k) for k in (1, 2, 2, 1)]
    for r in runs[1:]:
        assert np.array_equal(r.temperature_k, runs[0].temperature_k)
        assert np.array_equal(r.boundary_energy_j, runs[0].boundary_energy_j)
    assert runs[0].info["threads"] == 1 and runs[1].info["threads"] == 2


# ---------------------------------------------------------------- invariants
def test_adiabatic_closed_system_conserves_energy_and_obeys_max_principle():
    pk, h, c, rng = lattice((6, 6, 5), seed=4)
    prob = make_problem(c, pk.pair, h)
    T0 = 300.0 + 100.0 * rng.random(c.size)
    net = assemble(prob)
    dt = net.dt_max_s            # at the bound itself: still positive
    times = dt * np.arange(1000, 10001, 1000)
    r = run_explicit(net, T0, times, dt=dt)
    assert r.steps == 10_000
    e0 = np.dot(c, T0)
    drift = np.abs(r.temperature_k @ c - e0) / e0
    assert drift.max() <= 1e-12
    assert r.temperature_k.min() >= T0.min() and r.temperature_k.max() <= T0.max()
    # and it relaxes to the capacity-weighted mean
    assert np.ptp(r.temperature_k[-1]) < np.ptp(T0)


def test_maximum_principle_with_dirichlet_boundaries():
    prob, _ = two_face_problem((8, 5, 5), seed=5)
    rng = np.random.default_rng(5)
    T0 = 320.0 + 60.0 * rng.random(prob.capacity_j_k.size)   # inside [300, 400]
    r = run_explicit(prob, T0, np.linspace(0.5, 20.0, 40))
    assert r.temperature_k.min() >= 300.0 and r.temperature_k.max() <= 400.0


# ---------------------------------------------------------------- exact solution, agreement
def exact_transient(net, T0, t):
    """T(t) = T_ss + expm(-C^-1 K t)(T0 - T_ss) on the free particles (dense, small N)."""
    free = net.free
    lap = net.laplacian.toarray()
    K = lap[np.ix_(free, free)] + np.diag(net.exchange_g_w_k[free])
    td = np.where(net.held, net.held_temperature_k, 0.0)
    r = -(lap[free] @ td) + net.constant_rhs_w[free]
    tss = np.linalg.solve(K, r)
    A = -K / net.capacity_j_k[free][:, None]
    out = np.where(net.held, net.held_temperature_k, 0.0)
    out[free] = tss + scipy.linalg.expm(A * t) @ (T0[free] - tss)
    return out


def test_explicit_implicit_agree_with_exact_solution_and_orders():
    prob, _ = two_face_problem((5, 4, 3), seed=6)
    net = assemble(prob)
    T0 = np.full(net.n, 300.0)
    t_end = 2.0
    exact = exact_transient(net, T0, t_end)
    ref_scale = 100.0

    def err(method, dt):
        if method == "explicit":
            r = run_explicit(net, T0, [t_end], dt=dt)
        else:
            r = run_implicit(net, T0, [t_end], dt=dt, theta=method)
        return np.abs(r.temperature_k[-1] - exact).max() / ref_scale

    dt = t_end / 30                       # ~ dt_max / 2 here
    assert dt < net.dt_max_s / 2
    e_ex = [err("explicit", dt), err("explicit", dt / 2)]
    e_be = [err(1.0, dt), err(1.0, dt / 2)]
    e_cn = [err(0.5, dt), err(0.5, dt / 2)]
    # Stated tolerances (max error relative to the 100 K span) at dt ~ dt_max / 2 (measured:
    # explicit 5.1e-3, backward Euler 5.1e-3, Crank-Nicolson 5.8e-5) ...
    assert e_ex[0] < 1e-2 and e_be[0] < 1e-2 and e_cn[0] < 1e-4
    # ... and the orders: first (explicit, backward Euler), second (Crank-Nicolson).
    assert 1.8 < e_ex[0] / e_ex[1] < 2.2
    assert 1.8 < e_be[0] / e_be[1] < 2.2
    assert 3.6 < e_cn[0] / e_cn[1] < 4.4


def test_explicit_and_crank_nicolson_agree_at_the_same_dt():
    prob, _ = everything_problem(seed=8)
    net = assemble(prob)
    T0 = np.full(net.n, 320.0)
    times = [0.5, 1.0, 2.0, 3.0]
    diff = []
    for dt in (net.dt_max_s / 4, net.dt_max_s / 8):
        ex = run_explicit(net, T0, times, dt=dt)
        cn = run_implicit(net, T0, times, dt=dt, theta=0.5)
        span = ex.temperature_k.max() - ex.temperature_k.min()
        diff.append(np.abs(ex.temperature_k - cn.temperature_k).max() / span)
    # Stated tolerance at dt_max / 4: 6e-3 of the span (measured 3.8e-3; explicit's first-order
    # error dominates), and the difference halves with dt.
    assert diff[0] < 6e-3
    assert 1.7 < diff[0] / diff[1] < 2.3


def test_long_transient_reaches_steady_state():
    prob, _ = everything_problem(seed=9)
    net = assemble(prob)
    st = solve_steady(net)
    T0 = np.full(net.n, 330.0)
    be = run_implicit(net, T0, [1e3, 1e4], dt=50.0, theta=1.0)
    np.testing.assert_allclose(be.temperature_k[-1], st.temperature_k[0], rtol=0, atol=1e-8)
    ex = run_explicit(net, T0, [400.0])
    np.testing.assert_allclose(ex.temperature_k[-1], st.temperature_k[0], rtol=0, atol=1e-6)
    # the boundary heat flows approach the steady ones too
    np.testing.assert_allclose(be.boundary_heat_flow_w[-1], st.boundary_heat_flow_w[0],
                               atol=1e-7)


# ---------------------------------------------------------------- steady
def test_steady_heat_balance():
    prob, _ = everything_problem(seed=10)
    st = solve_steady(prob)
    flow = st.boundary_heat_flow_w[0]
    assert np.all(np.isfinite(st.temperature_k))
    assert "source_ignored" in st.flags
    # source_ignored: the source column is empty; what comes in goes out
    assert abs(flow.sum()) <= 1e-9 * np.abs(flow).sum()
    assert abs(st.info["heat_balance_relative"]) <= 1e-9
    # with the source included (its mean over the pulse), still balanced
    st2 = solve_steady(prob, source_interval=(0.5, 1.5))
    f2 = st2.boundary_heat_flow_w[0]
    assert f2[3] == pytest.approx(9.0)
    assert abs(f2.sum()) <= 1e-9 * np.abs(f2).sum()


def test_steady_chain_series_resistance_profile():
    rng = np.random.default_rng(11)
    n = 30
    h = 10.0 ** rng.uniform(-2, 2, n - 1)
    pair = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1)
    prob = make_problem(rng.uniform(1, 2, n), pair, h,
                        fixed=([0, n - 1], [400.0, 300.0], [0, 1]), boundary_names=("a", "b"))
    st = solve_steady(prob)
    q = 100.0 / np.sum(1.0 / h)
    expected = 400.0 - q * np.r_[0.0, np.cumsum(1.0 / h)]
    np.testing.assert_allclose(st.temperature_k[0], expected, rtol=1e-12)
    np.testing.assert_allclose(st.boundary_heat_flow_w[0], [q, -q], rtol=1e-10)


def test_steady_symmetric_case_is_mean_of_boundaries():
    pk, _, _, _ = lattice((6, 3, 3))
    m = pk.pair.shape[0]
    lo, hi = faces(pk)
    prob = make_problem(np.ones(pk.position.shape[0]), pk.pair, np.ones(m),
                        fixed=(np.r_[lo, hi], np.r_[np.full(lo.size, 300.0),
                                                    np.full(hi.size, 400.0)],
                               np.r_[np.zeros(lo.size), np.ones(hi.size)]))
    T = solve_steady(prob).temperature_k[0]
    x = pk.position[:, 0]
    np.testing.assert_allclose(T, 300.0 + 100.0 * (x - x.min()) / np.ptp(x), rtol=1e-12)


def test_steady_amg_matches_direct():
    prob, _ = two_face_problem((12, 10, 10), seed=12)
    d = solve_steady(prob, method="direct")
    a = solve_steady(prob, method="amg", tol=1e-12)
    assert a.info["linear_solver"] == "amg" and a.info["cg_iterations"][0] > 0
    np.testing.assert_allclose(a.temperature_k, d.temperature_k, rtol=0, atol=1e-8)
    assert abs(a.info["heat_balance_relative"]) < 1e-9


# ---------------------------------------------------------------- stability bound
def test_dt_above_bound_refused_with_the_bound_in_the_message():
    prob, _ = two_face_problem()
    net = assemble(prob)
    dt = net.dt_max_s * 1.0001
    with pytest.raises(UnstableTimeStepError, match=f"{net.dt_max_s:.6g}") as err:
        run_explicit(net, 300.0, [1.0], dt=dt)
    assert isinstance(err.value, ValueError) and "\n" not in str(err.value)
    r = run_explicit(net, 300.0, [1.0], dt=dt, allow_unstable=True)
    assert "dt_above_bound" in r.flags
    run_explicit(net, 300.0, [1.0], dt=net.dt_max_s)   # the bound itself is allowed


def hard_problem(seed=13):
    """Conductances log-uniform in 1e-6..1e6 W/K, capacities 1e-3..1e3 J/K with 2 % of
    particles 1e-6 times smaller; two Dirichlet faces."""
    pk, _, _, rng = lattice((10, 8, 8), seed)
    n, m = pk.position.shape[0], pk.pair.shape[0]
    h = 10.0 ** rng.uniform(-6, 6, m)
    c = 10.0 ** rng.uniform(-3, 3, n)
    c[rng.random(n) < 0.02] *= 1e-6
    lo, hi = faces(pk)
    prob = make_problem(c, pk.pair, h, fixed=(np.r_[lo, hi], np.r_[np.full(lo.size, 300.0),
                                                                    np.full(hi.size, 400.0)],
                                              np.r_[np.zeros(lo.size), np.ones(hi.size)]))
    return prob, rng


# slow: two 600-step explicit runs of the hard network;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_hard_case_default_dt_stays_positive_and_bound_is_tight():
    prob, rng = hard_problem()
    net = assemble(prob)
    T0 = 300.0 + 100.0 * rng.random(net.n)
    n_steps = 600
    ok = run_explicit(net, T0, [n_steps * net.dt_max_s])
    assert ok.dt == pytest.approx(0.9 * net.dt_max_s)
    assert ok.temperature_k.min() >= 300.0 and ok.temperature_k.max() <= 400.0
    # The paper's uniform estimate is far above the exact bound on such a network.
    assert net.dt_paper_s > 100 * net.dt_max_s
    # Above the bound positivity is lost at once (the critical particle overshoots) ...
    p = net.dt_max_particle
    T1 = T0.copy()
    T1[net.free] = 350.0
    T1[p] = 300.0 + 1e-3          # low particle among warmer neighbours
    one = explicit_step(net, T1, 1.5 * net.dt_max_s)
    assert one[p] > 350.0 + 1e-9
    # ... and above 2 dt_max (lambda_max >= max D/C) the run grows without bound.
    bad = run_explicit(net, T0, [n_steps * 2.05 * net.dt_max_s], dt=2.05 * net.dt_max_s,
                       allow_unstable=True)
    dev = np.abs(bad.temperature_k[-1][net.free] - 350.0)
    assert not np.all(np.isfinite(dev)) or dev.max() > 1e6
    assert "dt_above_bound" in bad.flags


def test_uniform_lattice_bound_is_tight_at_1_5_dt_max():
    """On a bipartite uniform lattice lambda_max ~ 2 max D/C: 1.5 dt_max already diverges, and
    the paper's estimate (uniform by construction) equals the exact bound."""
    pk, _, _, rng = lattice((8, 8, 8))
    n, m = pk.position.shape[0], pk.pair.shape[0]
    prob = make_problem(np.full(n, 2.0), pk.pair, np.full(m, 0.5))
    net = assemble(prob)
    assert net.dt_max_s == pytest.approx(2.0 / (6 * 0.5))
    assert net.dt_paper_s == pytest.approx(net.dt_max_s)
    T0 = 300.0 + rng.random(n)
    bad = run_explicit(net, T0, [300 * 1.5 * net.dt_max_s], dt=1.5 * net.dt_max_s,
                       allow_unstable=True)
    assert np.ptp(bad.temperature_k[-1]) > 1e6


# ---------------------------------------------------------------- clusters, rattlers
def floating_problem():
    """A lattice tied to two faces, plus a floating chain of 3 particles and a rattler."""
    prob, pk = two_face_problem((4, 3, 3), seed=14)
    n0 = prob.capacity_j_k.size
    rng = np.random.default_rng(14)
    c = np.r_[prob.capacity_j_k, rng.uniform(1, 3, 4)]
    pair = np.r_[prob.pair, [[n0, n0 + 1], [n0 + 1, n0 + 2]]]
    h = np.r_[prob.conductance_w_k, [1.0, 2.0]]
    p2 = make_problem(c, pair, h, fixed=(prob.fixed_particle, prob.fixed_temperature_k,
                                         prob.fixed_boundary),
                      boundary_names=prob.boundary_names)
    return p2, n0


def test_tied_clusters_by_hand():
    """Components 0-1-2 (a reservoir at 0), 3-4 and 5 alone, 6 alone but a reservoir: the one
    function behind net.clusters (assembly, the steady solver, tau in tdem_post.fits)."""
    import scipy.sparse as sp
    i, j = np.array([0, 1, 3]), np.array([1, 2, 4])
    adj = sp.coo_matrix((np.ones(3), (i, j)), shape=(7, 7)).tocsr()
    adj = (adj + adj.T).tocsr()
    reservoir = np.zeros(7, bool)
    reservoir[[0, 6]] = True
    c = tied_clusters(adj, reservoir)
    assert c.n_components == 4
    np.testing.assert_array_equal(c.tied_particle, [1, 1, 1, 0, 0, 0, 1])
    assert c.n_floating == 1 and list(c.floating_sizes) == [2]
    assert list(c.label[[3, 4]]) == [c.floating_clusters[0]] * 2
    assert list(c.rattlers) == [5]
    assert not c.tied.flags.writeable


def test_floating_cluster_and_rattler_steady_and_transient():
    prob, n0 = floating_problem()
    net = assemble(prob)
    assert net.clusters.n_floating == 1 and list(net.clusters.floating_sizes) == [3]
    assert list(net.clusters.rattlers) == [n0 + 3]
    assert "floating" in net.clusters.summary()
    T0 = np.full(net.n, 300.0)
    T0[n0:n0 + 4] = [310.0, 320.0, 330.0, 340.0]
    st = solve_steady(net, T0)
    T = st.temperature_k[0]
    assert np.all(np.isfinite(T))
    c = net.capacity_j_k[n0:n0 + 3]
    np.testing.assert_allclose(T[n0:n0 + 3], np.dot(c, T0[n0:n0 + 3]) / c.sum(), rtol=1e-14)
    assert T[n0 + 3] == 340.0
    assert st.info["floating_clusters"] == 1 and st.info["rattlers"] == 1
    assert {"floating_clusters", "rattlers"} <= set(st.flags)
    # without T0: finite, flagged
    st2 = solve_steady(net)
    assert np.all(np.isfinite(st2.temperature_k)) and "floating_without_T0" in st2.flags
    # transient: adiabatic evolution; the rattler keeps its temperature bit for bit
    ex = run_explicit(net, T0, [5.0, 50.0])
    assert np.all(ex.temperature_k[:, n0 + 3] == 340.0)
    e = ex.temperature_k[:, n0:n0 + 3] @ c
    np.testing.assert_allclose(e, np.dot(c, T0[n0:n0 + 3]), rtol=1e-14)
    np.testing.assert_allclose(ex.temperature_k[-1, n0:n0 + 3], T[n0:n0 + 3], rtol=1e-10)
    be = run_implicit(net, T0, [50.0], dt=1.0)
    assert be.temperature_k[-1, n0 + 3] == 340.0


def test_powered_floating_cluster_has_no_steady_state_and_is_flagged():
    prob, n0 = floating_problem()
    p = make_problem(prob.capacity_j_k, prob.pair, prob.conductance_w_k,
                     fixed=(prob.fixed_particle, prob.fixed_temperature_k,
                            prob.fixed_boundary),
                     power=([n0], [1.0], [0]), boundary_names=prob.boundary_names)
    st = solve_steady(p, np.full(p.capacity_j_k.size, 300.0))
    assert np.all(np.isfinite(st.temperature_k))
    assert "no_steady_state_in_floating_cluster" in st.flags
    # zero net power (in at one end, out at the other): a steady gradient, mean kept
    p = make_problem(prob.capacity_j_k, prob.pair, prob.conductance_w_k,
                     fixed=(prob.fixed_particle, prob.fixed_temperature_k,
                            prob.fixed_boundary),
                     power=([n0, n0 + 2], [1.0, -1.0], [0, 0]),
                     boundary_names=prob.boundary_names)
    T0 = np.full(p.capacity_j_k.size, 300.0)
    T = solve_steady(p, T0).temperature_k[0]
    assert T[n0] - T[n0 + 1] == pytest.approx(1.0) and T[n0 + 1] - T[n0 + 2] == pytest.approx(0.5)
    c = p.capacity_j_k[n0:n0 + 3]
    assert np.dot(c, T[n0:n0 + 3]) == pytest.approx(300.0 * c.sum(), rel=1e-14)


# ---------------------------------------------------------------- ledger
def test_energy_ledger_explicit_to_round_off_and_implicit_to_tolerance():
    prob, _ = everything_problem(seed=15)
    net = assemble(prob)
    T0 = 300.0 + 40.0 * np.random.default_rng(15).random(net.n)   # held ones jump to 300
    times = [0.25, 0.75, 1.25, 2.0, 3.0]
    ex = run_explicit(net, T0, times)
    scale = np.abs(ex.boundary_energy_j).sum(axis=1).max()
    assert scale > 1.0
    assert np.abs(ex.ledger_residual_j()).max() <= 1e-12 * scale * 10
    # the source's column holds the source heat, repeated in source_energy_j
    np.testing.assert_array_equal(ex.boundary_energy_j[:, 3], ex.source_energy_j)
    assert ex.source_energy_j[-1] == pytest.approx(9.0, rel=1e-12)
    for theta, scheme in ((1.0, "theta"), (0.5, "theta"), (0.5, "rannacher"), (0.5, "tr-bdf2")):
        im = run_implicit(net, T0, times, dt=0.05, theta=theta, scheme=scheme)
        assert np.abs(im.ledger_residual_j()).max() <= 1e-9 * scale
        assert im.source_energy_j[-1] == pytest.approx(9.0, rel=1e-12)
    # boundary heat flow is the derivative of boundary energy (checked on the power column)
    np.testing.assert_allclose(ex.boundary_heat_flow_w[:, 2],
                               net.constant_boundary_flow_w[2], rtol=1e-15)
    # 0.9 W enters through the heater; the 0.4 W of it that lands on a held particle leaves
    # through that particle's Dirichlet boundary
    assert net.constant_boundary_flow_w[2] == pytest.approx(0.9)
    assert net.constant_boundary_flow_w[0] == pytest.approx(-0.4)


# ---------------------------------------------------------------- checkpoint / resume
@pytest.mark.parametrize("solver", ["explicit", "implicit", "rannacher", "tr-bdf2"])
def test_checkpoint_two_halves_equal_one_run_bit_for_bit(solver):
    prob, _ = everything_problem(seed=16)
    net = assemble(prob)
    T0 = np.full(net.n, 310.0)
    if solver == "explicit":
        def run(start, times):
            return run_explicit(net, start, times)
    elif solver == "implicit":
        def run(start, times):
            return run_implicit(net, start, times, dt=0.07, theta=0.5)
    else:
        # 7 start-up steps: the split at 0.3 s (5 steps) falls inside the start-up
        def run(start, times):
            return run_implicit(net, start, times, dt=0.07, scheme=solver, startup_steps=7)
    full = run(T0, [0.3, 1.1, 2.0])
    a = run(T0, [0.3, 1.1])
    b = run(a.state, [2.0])
    assert np.array_equal(b.temperature_k[-1], full.temperature_k[-1])
    assert np.array_equal(b.boundary_energy_j[-1], full.boundary_energy_j[-1])
    assert b.source_energy_j[-1] == full.source_energy_j[-1]
    assert b.state.step == full.state.step and b.state.time_s == 2.0


# ---------------------------------------------------------------- validation, progress
@pytest.mark.parametrize("change, message", [
    (dict(conductance_w_k=-1.0), "conductance_w_k: must be >= 0"),
    (dict(conductance_w_k=np.nan), "conductance_w_k: 1 non-finite"),
    (dict(capacity_j_k=0.0), "capacity_j_k: must be > 0"),
    (dict(capacity_j_k=np.inf), "capacity_j_k: 1 non-finite"),
])
def test_validation_refuses_bad_values(change, message):
    pk, h, c, _ = lattice((3, 3, 3))
    (key, value), = change.items()
    arrays = dict(capacity_j_k=c, conductance_w_k=h)
    arrays[key] = arrays[key].copy()
    arrays[key][4] = value
    with pytest.raises(NetworkError, match=message):
        assemble(make_problem(arrays["capacity_j_k"], pk.pair, arrays["conductance_w_k"]))


def test_validation_refuses_bad_pairs():
    pk, h, c, _ = lattice((3, 3, 3))
    with pytest.raises(NetworkError, match="not i < j"):
        assemble(make_problem(c, pk.pair[:, ::-1], h))
    with pytest.raises(NetworkError, match="more than once"):
        assemble(make_problem(c, np.r_[pk.pair, pk.pair[:1]], np.r_[h, h[:1]]))
    with pytest.raises(NetworkError, match="out of range"):
        assemble(make_problem(c[:-1], pk.pair, h))


def test_progress_callback_and_zero_conductance_contacts():
    prob, _ = two_face_problem()
    h = prob.conductance_w_k.copy()
    h[:5] = 0.0
    p = make_problem(prob.capacity_j_k, prob.pair, h, fixed=(prob.fixed_particle,
                     prob.fixed_temperature_k, prob.fixed_boundary))
    calls = []
    r = run_explicit(p, 300.0, [0.0, 2.0, 4.0], progress=lambda *a: calls.append(a))
    assert calls[-1] == (r.steps, r.steps, 4.0)
    assert "zero_conductance_contacts_dropped" in r.flags
    assert r.temperature_k.shape == (3, p.capacity_j_k.size)
    assert np.array_equal(r.temperature_k[0][~np.isin(np.arange(p.capacity_j_k.size),
                                                       p.fixed_particle)], np.full(
        p.capacity_j_k.size - p.fixed_particle.size, 300.0))
    assert r.contact_updates_per_second > 0


def test_no_conduction_only_power_is_exact():
    """No contact conducts (dt_max = inf): one step per output interval, exact for constant
    power; all particles are rattlers."""
    c = np.array([1.0, 2.0, 4.0])
    prob = make_problem(c, np.zeros((0, 2)), np.zeros(0), power=([0, 2], [1.0, 2.0], [0, 0]))
    net = assemble(prob)
    assert net.dt_max_s == np.inf and net.clusters.n_rattlers == 3
    r = run_explicit(net, 300.0, [1.0, 3.0])
    np.testing.assert_allclose(r.temperature_k[-1], [303.0, 300.0, 301.5], rtol=1e-15)
    assert r.steps == 2
    np.testing.assert_allclose(r.ledger_residual_j(), 0.0, atol=1e-12)
    st = solve_steady(net, 300.0)
    # powered rattlers heat for ever: flagged, kept at T0 (never a NaN)
    assert "no_steady_state_in_floating_cluster" in st.flags
    assert [c for c, _ in st.info["no_steady_state"]] != []
    assert np.all(st.temperature_k == 300.0)


# ---------------------------------------------------------------- stiff modes: second-order schemes
def test_second_order_schemes_converge_at_second_order_to_the_exact_solution():
    """Against expm (eigen-decomposition of the small network): Crank-Nicolson with Rannacher
    start-up and TR-BDF2 are second order, also at steps 10-40x the fastest time constant."""
    prob, _ = two_face_problem((5, 4, 3), seed=6)
    net = assemble(prob)
    T0 = np.full(net.n, 300.0)
    t_end = 4.0
    exact = exact_transient(net, T0, t_end)
    for scheme in ("rannacher", "tr-bdf2"):
        errs = [np.abs(run_implicit(net, T0, [t_end], dt=dt, scheme=scheme).temperature_k[-1]
                       - exact).max() for dt in (0.1, 0.05, 0.025)]
        assert errs[0] < 1e-2 * 100.0                        # span 100 K
        assert 3.4 < errs[0] / errs[1] < 4.6 and 3.4 < errs[1] / errs[2] < 4.6, (scheme, errs)


def stiff_bed_network(tmp_path):
    """The issue's stiff case: the 300-sphere YADE bed (dt_max 0.097 s), law pipe, bottom wall
    500 K, plate 400 K, bed at 300 K."""
    from pathlib import Path
    from tdem.committed_beds import BED_THERMAL
    from thermal_kernel.packing import read_packing
    from thermal_kernel.problem import build_problem
    from thermal_kernel.scene import load_scene
    packing = Path(__file__).parent / "data" / "bed_small_4.05e+07Pa.h5"
    scene = tmp_path / "stiff.toml"
    scene.write_text(f'packing = "{packing}"\nlaw = "pipe"\n' + BED_THERMAL
                     + '[solver]\nmethod = "implicit"\ntheta = 0.5\ndt = 5.0\nend_time = 5.0\n')
    sc = load_scene(scene)
    prob, _ = build_problem(sc, read_packing(packing))
    return sc, assemble(prob)


def test_stiff_bed_default_second_order_scheme_obeys_maximum_principle_plain_cn_rings(tmp_path):
    sc, net = stiff_bed_network(tmp_path)
    # theta = 0.5 in a scene means the default second-order scheme
    assert sc.solver.scheme == "rannacher"
    T0 = np.full(net.n, 300.0)
    lo, hi, span = 300.0, 500.0, 200.0
    assert 5.0 / net.dt_max_s > 50                   # dt >> the fastest time constant
    # the recipe: one output at 5 s (reached in the backward-Euler start-up): exact
    T = run_implicit(net, T0, [5.0], dt=5.0, scheme=sc.solver.scheme).temperature_k
    assert T.min() >= lo - 1e-9 * span and T.max() <= hi + 1e-9 * span, (T.min(), T.max())
    # an output after every step, dt = 10-200 dt_max: within 1e-2 of the span (measured worst
    # 5.0e-3 at dt = 4 s; second-order schemes cannot be positive for every dt)
    for dt in (1.0, 2.0, 4.0, 5.0, 10.0, 20.0):
        T = run_implicit(net, T0, dt * np.arange(1, 41), dt=dt,
                         scheme=sc.solver.scheme).temperature_k
        assert T.min() >= lo - 1e-2 * span and T.max() <= hi + 1e-2 * span, (dt, T.max())
    # plain Crank-Nicolson (scheme = "theta", theta = 0.5) rings: documented, kept selectable
    cn = run_implicit(net, T0, [5.0], dt=5.0, theta=0.5, scheme="theta").temperature_k
    assert cn.max() > hi + 0.3 * span                # measured 595.6 K
    # and the default converges at second order on the stiff case (reference: dt = 1e-3 s)
    times = [5.0, 10.0, 20.0]
    ref = run_implicit(net, T0, times, dt=1e-3, scheme="rannacher").temperature_k
    errs = [np.abs(run_implicit(net, T0, times, dt=dt, scheme="rannacher").temperature_k
                   - ref).max() for dt in (0.5, 0.25, 0.125)]
    assert errs[0] < 0.5                             # measured 0.24 K, span 200 K
    assert 3.4 < errs[0] / errs[1] < 4.6 and 3.4 < errs[1] / errs[2] < 4.6, errs


def test_scene_solver_scheme_options(tmp_path):
    from tdem.committed_beds import BED_THERMAL
    from thermal_kernel.scene import SceneError, load_scene

    def scene(extra, method="implicit"):
        p = tmp_path / "s.toml"
        p.write_text('packing = "x.h5"\nlaw = "pipe"\n' + BED_THERMAL
                     + f'[solver]\nmethod = "{method}"\nend_time = 1.0\ndt = 0.1\n' + extra)
        return load_scene(p).solver

    assert (scene("").scheme, scene("theta = 1.0\n").scheme) == ("theta", "theta")
    assert scene("theta = 0.5\n").scheme == "rannacher"
    assert scene("theta = 0.5\nscheme = \"theta\"\n").scheme == "theta"
    s = scene("scheme = \"tr-bdf2\"\nstartup_steps = 1\n")
    assert (s.scheme, s.startup_steps) == ("tr-bdf2", 1)
    for extra, key in (("scheme = \"bdf9\"\n", "solver.scheme"),
                       ("theta = 0.7\nscheme = \"rannacher\"\n", "solver.theta"),
                       ("startup_steps = -1\nscheme = \"rannacher\"\n", "solver.startup_steps"),
                       ("startup_steps = 2\n", "solver.startup_steps")):
        with pytest.raises(SceneError, match=key):
            scene(extra)
    with pytest.raises(SceneError, match="solver.scheme"):
        scene("scheme = \"rannacher\"\n", method="explicit")


def test_amg_setup_gives_the_same_bits_every_run_and_leaves_the_global_generator():
    """The AMG-CG path (SpdSolver, method "amg": every steady and implicit solve above
    DIRECT_MAX unknowns) builds its hierarchy with numpy's global generator seeded (pyamg's
    spectral-radius estimate starts from np.random.rand): two setups on one matrix give the same
    solution bit for bit whatever the generator's state, and the caller's stream goes on as if
    nothing had drawn from it."""
    import scipy.sparse as sp

    from thermal_kernel.solvers.implicit import SpdSolver
    rng = np.random.default_rng(7)
    n = 3000
    i = rng.integers(0, n, 4 * n)
    j = rng.integers(0, n, 4 * n)
    w = rng.uniform(0.1, 1.0, 4 * n)
    adj = sp.coo_matrix((np.r_[w, w], (np.r_[i, j], np.r_[j, i])), shape=(n, n)).tocsr()
    m = (sp.diags(np.asarray(adj.sum(axis=1)).ravel() + 0.01) - adj).tocsr()
    r = rng.normal(size=n)
    solutions = []
    for seed in (1, 2):
        np.random.seed(seed)
        x = SpdSolver(m, method="amg", tol=1e-10).solve(r)
        after = np.random.rand()
        np.random.seed(seed)
        assert after == np.random.rand()        # the setup drew nothing from the caller's stream
        solutions.append(x)
    np.testing.assert_array_equal(solutions[0], solutions[1])
    assert np.linalg.norm(m @ solutions[0] - r) <= 1e-9 * np.linalg.norm(r)
