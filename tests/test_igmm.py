"""IGMM (Engel & Heinen 2010) and GMR (seed A Eq. 5, 6): properties, oracles, persistence."""

from __future__ import annotations

import json
import math
import tracemalloc

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.learn.mixtures.gmr import GMRConditional, gmr_predict
from ccm.learn.mixtures.igmm import IGMM, chi2_quantile

IN6, OUT6 = [0, 1, 2, 3], [4, 5]
SIG6 = [0.01, 0.005, 0.5, 0.03, 0.5, 0.03]


def porridge_stream(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """AVIC-like 6-D stream X_t = [S_{t-1}, D_t] (seed A Eq. 2, 3) and the states S_t."""
    rng = np.random.default_rng(seed)
    t = np.arange(n + 1) * 1e-3
    v = 0.2 * (1.0 + 0.5 * np.sin(2 * np.pi * 0.5 * t)) + 0.002 * rng.normal(size=n + 1)
    w = np.abs(0.05 * np.sin(2 * np.pi * 0.3 * t) + 0.001 * rng.normal(size=n + 1))
    c = 20.0 + 40.0 * t / t[-1]
    force = np.abs(c * v + 0.2 * rng.normal(size=n + 1))
    torque = np.abs(0.05 * force + 0.01 * rng.normal(size=n + 1))
    s = np.c_[np.abs(v), w, force, torque]
    return np.c_[s[:-1], s[1:, 2:]], s


def assert_pd(model: IGMM) -> None:
    covs = model.covariances_
    assert covs.shape[0] == model.n_components_ >= 1
    np.testing.assert_array_equal(covs, np.swapaxes(covs, 1, 2))
    eig = np.linalg.eigvalsh(covs)
    assert np.all(eig > 0.0)
    assert eig.min() >= model.cov_floor * (1.0 - 1e-6)
    np.linalg.cholesky(covs)  # raises if not positive definite
    assert np.all(np.isfinite(model.means_))
    np.testing.assert_allclose(model.weights_.sum(), 1.0, rtol=1e-12)


def random_mixture(rng: np.random.Generator, k: int, d: int):
    w = rng.uniform(0.2, 1.0, k)
    w /= w.sum()
    mu = rng.normal(scale=2.0, size=(k, d))
    a = rng.normal(size=(k, d, d))
    cov = a @ np.swapaxes(a, 1, 2) + 0.5 * np.eye(d)
    return w, mu, cov


# ---------------------------------------------------------------------------------------------
# a plain numpy statement of the algorithm, to check the numba kernels against
# ---------------------------------------------------------------------------------------------


def reference_igmm(X, sigma_init, q, v_min, sp_min, floor):
    """Engel & Heinen 2010 as documented in ccm.learn.mixtures.igmm (no overflow), slow and
    plain."""
    d = X.shape[1]
    thr = chi2_quantile(q, d)
    mus, covs, sps, vs = [], [], [], []
    for x in X:
        m2 = [float((x - m) @ np.linalg.solve(c, x - m)) for m, c in zip(mus, covs, strict=True)]
        if all(v >= thr for v in m2):
            mus.append(x.copy())
            covs.append(np.diag(np.broadcast_to(np.asarray(sigma_init, float), (d,)) ** 2))
            sps.append(1.0)
            vs.append(1)
            continue
        logp = np.array(
            [
                math.log(sp) - 0.5 * np.linalg.slogdet(c)[1] - 0.5 * m
                for sp, c, m in zip(sps, covs, m2, strict=True)
            ]
        )
        post = np.exp(logp - logp.max())
        post /= post.sum()
        for j in range(len(mus)):
            vs[j] += 1
            if post[j] == 0.0:
                continue
            sps[j] += post[j]
            w = post[j] / sps[j]
            e = x - mus[j]
            mus[j] = mus[j] + w * e
            covs[j] = (1 - w) * covs[j] + w * (1 - w) * np.outer(e, e) + w * floor * np.eye(d)
        bad = [j for j in range(len(mus)) if vs[j] > v_min and sps[j] < sp_min]
        if len(bad) == len(mus):
            bad.remove(max(bad, key=lambda j: sps[j]))
        for j in reversed(bad):
            for lst in (mus, covs, sps, vs):
                del lst[j]
    sp = np.array(sps)
    return sp / sp.sum(), np.array(mus), np.array(covs), np.array(vs)


def test_kernels_match_plain_numpy_statement_of_the_algorithm():
    rng = np.random.default_rng(3)
    centres = np.array([[0.0, 0.0, 0.0], [4.0, 0.0, 1.0], [0.0, 5.0, -2.0]])
    X = centres[rng.integers(0, 3, 400)] + rng.normal(scale=0.6, size=(400, 3))
    X[::37] += rng.normal(scale=8.0, size=(X[::37].shape))  # outliers: create, then prune
    kw = {"sigma_init": 0.8, "v_min": 5, "sp_min": 3.0, "cov_floor": 1e-6}
    model = IGMM(3, max_components=50, **kw).partial_fit(X)
    w, mu, cov, ages = reference_igmm(X, 0.8, 0.99, 5, 3.0, 1e-6)
    assert model.stats_["support_pruned"] > 0 and model.stats_["created"] > 3
    assert model.n_components_ == len(w)
    np.testing.assert_allclose(model.weights_, w, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(model.means_, mu, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(model.covariances_, cov, rtol=1e-8, atol=1e-10)
    np.testing.assert_array_equal(model.ages_, ages)
    assert model.n_seen_ == 400


def test_chi2_threshold_and_tau_equivalence():
    model = IGMM(6, sigma_init=1.0)
    assert model.novelty_threshold_ == pytest.approx(16.811893829770927, rel=1e-12)  # chi2(6) 99 %
    assert chi2_quantile(0.95, 2) == pytest.approx(-2 * math.log(0.05), rel=1e-12)
    assert model.novelty_tau_ == pytest.approx(math.exp(-0.5 * model.novelty_threshold_))
    assert IGMM(2).get_params()["sigma_init"] == [0.1, 0.1]  # default for order-one features


# ---------------------------------------------------------------------------------------------
# positive definiteness on adversarial streams
# ---------------------------------------------------------------------------------------------


def test_constant_input_stays_positive_definite():
    x = np.array([0.3, 0.0, 12.0, 0.5, 12.0, 0.5])
    model = IGMM(6, sigma_init=SIG6)
    model.partial_fit(np.tile(x, (20_000, 1)))
    assert model.n_components_ == 1
    np.testing.assert_allclose(model.means_[0], x, rtol=1e-14)
    assert_pd(model)
    # the data variance is 0: the covariance shrinks to the floor but not below it
    assert np.linalg.eigvalsh(model.covariances_[0]).max() < 1e-4
    mean, cov = model.predict_cov(x[:4], IN6, OUT6)
    np.testing.assert_allclose(mean, x[4:], rtol=1e-12)
    assert np.all(np.linalg.eigvalsh(cov) > 0.0)


def test_zero_velocity_dimensions_stay_positive_definite():
    X, _ = porridge_stream(20_000, seed=1)
    X[:, 0] = 0.0  # robot held still: |v_lin| = 0
    X[:, 1] = 0.0  # no rotation: |v_rot| = 0
    model = IGMM(6, sigma_init=SIG6).partial_fit(X)
    assert_pd(model)
    assert model.stats_["jitter"] == 0
    assert np.all(np.abs(model.means_[:, :2]) == 0.0)


def test_jump_of_100_sigma_stays_positive_definite():
    rng = np.random.default_rng(2)
    sig = np.array(SIG6)
    base = np.array([0.2, 0.02, 8.0, 0.4, 8.0, 0.4])
    before = base + sig * rng.normal(size=(3000, 6))
    after = base + 100.0 * sig + sig * rng.normal(size=(3000, 6))
    model = IGMM(6, sigma_init=sig)
    for x in before:
        model.partial_fit(x)
    assert_pd(model)
    k_before = model.n_components_
    model.partial_fit(after[0])  # far beyond every component: novel
    assert model.n_components_ == k_before + 1
    assert_pd(model)
    model.partial_fit(after[1:])
    assert_pd(model)
    dist = np.linalg.norm((model.means_ - (base + 100 * sig)) / sig, axis=1)
    assert dist.min() < 1.0


def test_point_beyond_2_sigma_of_young_component_stays_positive_definite():
    """The case that breaks the commonly quoted Engel & Heinen update: w ~ 0.5, e > 2 sigma."""
    rng = np.random.default_rng(5)
    for _ in range(50):
        model = IGMM(4, sigma_init=1.0, novelty_chi2_quantile=0.999999)
        model.partial_fit(np.zeros(4))
        for _ in range(12):
            direction = rng.normal(size=4)
            model.partial_fit(4.0 * direction / np.linalg.norm(direction))
        assert_pd(model)


def test_long_realistic_stream_stays_positive_definite():
    X, _ = porridge_stream(100_000, seed=4)
    model = IGMM(6, sigma_init=SIG6, max_components=20)
    for chunk in np.array_split(X, 10):
        model.partial_fit(chunk)
        assert_pd(model)
        assert model.n_components_ <= 20
    assert model.n_seen_ == 100_000
    assert model.stats_["jitter"] == 0


# ---------------------------------------------------------------------------------------------
# GMR against the `gmr` package (test oracle only)
# ---------------------------------------------------------------------------------------------


def oracle(weights, means, covs, x_in, in_idx, out_idx):
    gmr = pytest.importorskip("gmr")
    g = gmr.GMM(len(weights), priors=weights, means=means, covariances=covs)
    mvn = g.condition(list(in_idx), np.asarray(x_in)).to_mvn()
    # the oracle returns the complement of in_idx in ascending order
    rest = sorted(set(range(means.shape[1])) - set(in_idx))
    perm = [rest.index(i) for i in out_idx]
    return mvn.mean[perm], mvn.covariance[np.ix_(perm, perm)]


@pytest.mark.parametrize("seed", range(6))
def test_gmr_matches_oracle_on_random_mixtures(seed):
    rng = np.random.default_rng(seed)
    k, d = int(rng.integers(1, 6)), int(rng.integers(2, 7))
    w, mu, cov = random_mixture(rng, k, d)
    perm = rng.permutation(d)
    n_in = int(rng.integers(1, d))
    in_idx, out_idx = perm[:n_in].tolist(), perm[n_in:].tolist()
    cond = GMRConditional(w, mu, cov, in_idx, out_idx)
    X = mu[rng.integers(0, k, 8)][:, in_idx] + rng.normal(scale=1.5, size=(8, n_in))
    batch_mean, batch_cov = cond.predict_cov(X)
    np_mean, np_cov = gmr_predict(w, mu, cov, X, in_idx, out_idx)
    for i, x in enumerate(X):
        o_mean, o_cov = oracle(w, mu, cov, x, in_idx, out_idx)
        m1, c1 = cond.predict_cov(x)
        for mean_, cov_ in ((m1, c1), (batch_mean[i], batch_cov[i]), (np_mean[i], np_cov[i])):
            np.testing.assert_allclose(mean_, o_mean, rtol=0, atol=1e-9)
            np.testing.assert_allclose(cov_, o_cov, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(cond.predict(x), m1)


def test_gmr_matches_oracle_on_fitted_igmm():
    X, S = porridge_stream(20_000, seed=7)
    model = IGMM(6, sigma_init=SIG6).partial_fit(X)
    assert model.n_components_ >= 3
    w, mu, cov = model.weights_, model.means_, model.covariances_
    worst = 0.0
    for s in S[::997]:
        o_mean, o_cov = oracle(w, mu, cov, s, IN6, OUT6)
        mean, c = model.predict_cov(s, IN6, OUT6)
        scale = max(1.0, np.abs(o_mean).max())
        worst = max(worst, np.abs(mean - o_mean).max() / scale, np.abs(c - o_cov).max())
        np.testing.assert_array_equal(model.predict(s, IN6, OUT6), mean)
    assert worst < 1e-9


def test_gmr_output_subset_and_order_marginalise():
    rng = np.random.default_rng(11)
    w, mu, cov = random_mixture(rng, 3, 5)
    x = rng.normal(size=2)
    mean, c = gmr_predict(w, mu, cov, x, [3, 0], [4, 1])  # dim 2 marginalised out
    keep = [0, 1, 3, 4]
    ref_mean, ref_cov = gmr_predict(w, mu[:, keep], cov[:, keep][:, :, keep], x, [2, 0], [3, 1])
    np.testing.assert_allclose(mean, ref_mean, atol=1e-12)
    np.testing.assert_allclose(c, ref_cov, atol=1e-12)
    m2, c2 = GMRConditional(w, mu, cov, [3, 0], [4, 1]).predict_cov(x)
    np.testing.assert_allclose(m2, mean, atol=1e-12)
    np.testing.assert_allclose(c2, c, atol=1e-12)


@pytest.mark.parametrize("overflow", ["merge", "prune"])
def test_gmr_cache_follows_model_updates(overflow):
    """The per-component refresh (change stamps) stays exact through creation, update,
    support pruning and overflow merges/drops, for a leading and a scattered split."""
    X, S = porridge_stream(3000, seed=8)
    for i in range(120, 3000, 50):  # bursts of 6 novel points: overflow events
        X[i : i + 6] += 40.0 * np.array(SIG6) * np.arange(1.0, 7.0)[:, None]
    model = IGMM(6, sigma_init=SIG6, max_components=5, overflow=overflow)
    cond = model.conditional(IN6, OUT6)
    assert model.conditional(IN6, OUT6) is cond
    assert model.conditional(np.array(IN6), tuple(OUT6)) is cond
    other_in, other_out = [5, 2, 0], [3, 1]
    other = model.conditional(other_in, other_out)
    model.partial_fit(X[:100])
    for i in range(100, 700):
        model.partial_fit(X[i])
        w, mu, cov = model.weights_, model.means_, model.covariances_
        mean, c = cond.predict_cov(S[i + 1])
        ref_mean, ref_cov = gmr_predict(w, mu, cov, S[i + 1], IN6, OUT6)
        np.testing.assert_allclose(mean, ref_mean, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(c, ref_cov, rtol=1e-8, atol=1e-12)
        x_other = X[i + 1, other_in]
        ref_mean, ref_cov = gmr_predict(w, mu, cov, x_other, other_in, other_out)
        mean, c = other.predict_cov(x_other)
        np.testing.assert_allclose(mean, ref_mean, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(c, ref_cov, rtol=1e-8, atol=1e-12)
    stats = model.stats_
    assert stats["merged"] + stats["overflow_pruned"] >= 2 and stats["support_pruned"] > 0
    model.reset()
    with pytest.raises(ValueError, match="no components"):
        cond.predict(S[0])
    model.partial_fit(X[:50])  # after a reset the cache must not serve old components
    np.testing.assert_allclose(
        cond.predict(S[60]),
        gmr_predict(model.weights_, model.means_, model.covariances_, S[60], IN6, OUT6)[0],
        rtol=1e-10,
    )


def test_gmr_with_frozen_sklearn_mixture():
    from sklearn.mixture import GaussianMixture

    X, S = porridge_stream(4000, seed=9)
    gm = GaussianMixture(4, covariance_type="full", random_state=0).fit(X)
    mean, c = gmr_predict(gm.weights_, gm.means_, gm.covariances_, S[:50], IN6, OUT6)
    o_mean, o_cov = oracle(gm.weights_, gm.means_, gm.covariances_, S[10], IN6, OUT6)
    np.testing.assert_allclose(mean[10], o_mean, atol=1e-9)
    np.testing.assert_allclose(c[10], o_cov, atol=1e-9)
    cond = GMRConditional(gm.weights_, gm.means_, gm.covariances_, IN6, OUT6)
    np.testing.assert_allclose(cond.predict(S[:50]), mean, atol=1e-9)


# ---------------------------------------------------------------------------------------------
# recovering a known mixture
# ---------------------------------------------------------------------------------------------


def test_recovers_known_mixture_like_sklearn():
    """Means within 0.15 (component std >= 0.4) and weights within 0.03 of a sklearn EM fit."""
    from sklearn.mixture import GaussianMixture

    rng = np.random.default_rng(0)
    true_w = np.array([0.5, 0.3, 0.2])
    true_mu = np.array([[0.0, 0.0, 0.0], [6.0, 1.0, -2.0], [-1.0, 7.0, 3.0]])
    true_sd = np.array([[0.6, 0.4, 0.5], [0.5, 0.8, 0.4], [0.7, 0.5, 0.6]])
    labels = rng.choice(3, size=6000, p=true_w)
    X = true_mu[labels] + true_sd[labels] * rng.normal(size=(6000, 3))

    streamed = IGMM(3, sigma_init=1.0)
    for x in X:
        streamed.partial_fit(x)
    batch = IGMM(3, sigma_init=1.0).partial_fit(X)
    np.testing.assert_array_equal(streamed.means_, batch.means_)  # same sequential algorithm
    np.testing.assert_array_equal(streamed.covariances_, batch.covariances_)
    refit = IGMM(3, sigma_init=1.0).fit(X[:100]).fit(X)
    np.testing.assert_array_equal(refit.means_, batch.means_)

    gm = GaussianMixture(3, covariance_type="full", n_init=3, random_state=0).fit(X)
    assert batch.n_components_ == 3
    order_i = np.argsort(batch.means_[:, 0] + 0.1 * batch.means_[:, 1])
    order_s = np.argsort(gm.means_[:, 0] + 0.1 * gm.means_[:, 1])
    np.testing.assert_allclose(batch.means_[order_i], gm.means_[order_s], atol=0.15)
    np.testing.assert_allclose(batch.weights_[order_i], gm.weights_[order_s], atol=0.03)
    np.testing.assert_allclose(
        np.sqrt(np.diagonal(batch.covariances_[order_i], axis1=1, axis2=2)),
        np.sqrt(np.diagonal(gm.covariances_[order_s], axis1=1, axis2=2)),
        atol=0.1,
    )
    # and the log-likelihood (Eq. 5) is close to the EM optimum
    assert batch.score(X) > gm.score(X) - 0.02


def test_score_samples_is_the_mixture_log_density():
    from scipy.stats import multivariate_normal

    X, _ = porridge_stream(5000, seed=12)
    model = IGMM(6, sigma_init=SIG6).partial_fit(X)
    pts = X[::501]
    dens = sum(
        w * multivariate_normal(m, c).pdf(pts)
        for w, m, c in zip(model.weights_, model.means_, model.covariances_, strict=True)
    )
    np.testing.assert_allclose(model.score_samples(pts), np.log(dens), rtol=1e-10)
    assert model.score_samples(pts[0]).shape == (1,)


# ---------------------------------------------------------------------------------------------
# bounded size, flat memory
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("overflow", ["merge", "prune"])
def test_component_count_bounded_over_many_novel_points(overflow):
    rng = np.random.default_rng(1)
    model = IGMM(3, sigma_init=0.1, max_components=8, overflow=overflow, sp_min=0.0)
    for _ in range(40):
        model.partial_fit(rng.uniform(-100, 100, size=(50, 3)))  # nearly every point novel
        assert model.n_components_ <= 8
    assert model.n_components_ == 8
    stats = model.stats_
    if overflow == "merge":
        # merged components are wide, so later points are novel less often
        assert stats["merged"] > 20 and stats["overflow_pruned"] == 0
        assert stats["created"] == 8 + stats["merged"]
    else:
        assert stats["overflow_pruned"] > 1500 and stats["merged"] == 0
        assert stats["created"] == 8 + stats["overflow_pruned"]
    assert_pd(model)


def test_merge_moment_matches_the_closest_pair():
    mu = np.array([[0.0, 0.0], [0.3, 0.1], [10.0, 0.0]])
    cov = np.array([np.eye(2), [[0.5, 0.1], [0.1, 0.7]], np.eye(2)])
    sp = np.array([4.0, 2.0, 3.0])
    data = IGMM(2, sigma_init=1.0, max_components=3).state_dict()
    data.update(means=mu.tolist(), covariances=cov.tolist(), support=sp.tolist(), ages=[9, 9, 9])
    model = IGMM.from_state_dict(data)
    x_new = np.array([0.0, 50.0])
    model.partial_fit(x_new)
    a, b = 4.0 / 6.0, 2.0 / 6.0
    d = mu[0] - mu[1]
    mean01 = a * mu[0] + b * mu[1]
    cov01 = a * cov[0] + b * cov[1] + a * b * np.outer(d, d)
    np.testing.assert_allclose(model.means_, [mean01, mu[2], x_new], atol=1e-14)
    np.testing.assert_allclose(model.covariances_[0], cov01, atol=1e-14)
    np.testing.assert_allclose(model.support_, [6.0, 3.0, 1.0])
    assert model.stats_["merged"] == 1


def test_prune_overflow_drops_least_support():
    mu = np.array([[0.0, 0.0], [3.0, 0.0], [10.0, 0.0]])
    data = IGMM(2, sigma_init=1.0, max_components=3, overflow="prune").state_dict()
    data.update(
        means=mu.tolist(),
        covariances=[np.eye(2).tolist()] * 3,
        support=[4.0, 2.0, 3.0],
        ages=[9, 9, 9],
    )
    model = IGMM.from_state_dict(data)
    model.partial_fit([0.0, 50.0])
    np.testing.assert_allclose(model.means_, [[0.0, 0.0], [10.0, 0.0], [0.0, 50.0]])
    assert model.stats_["overflow_pruned"] == 1


def test_memory_flat_over_a_long_stream():
    X, S = porridge_stream(30_000, seed=13)
    model = IGMM(6, sigma_init=SIG6, max_components=20)
    cond = model.conditional(IN6, OUT6)
    model.partial_fit(X[:1000])
    cond.predict(S[1000])
    buffers = {k: v for k, v in vars(model).items() if isinstance(v, np.ndarray)}
    buffers.update({f"cond.{k}": v for k, v in vars(cond).items() if isinstance(v, np.ndarray)})
    shapes = {k: (v.shape, id(v)) for k, v in buffers.items()}
    nbytes = model.nbytes()

    def run(lo, hi):
        for i in range(lo, hi):
            model.partial_fit(X[i])
            cond.predict(S[i + 1])

    run(1000, 2000)  # warm up allocator caches
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    run(2000, 29_000)
    after = tracemalloc.get_traced_memory()[0]
    tracemalloc.stop()
    assert after - before < 4096  # bytes; nothing accumulates per step
    assert model.nbytes() == nbytes
    for k, v in buffers.items():
        assert (v.shape, id(v)) == shapes[k], k
    assert model.n_components_ <= 20


# ---------------------------------------------------------------------------------------------
# persistence
# ---------------------------------------------------------------------------------------------


def fitted_model(overflow="merge"):
    X, _ = porridge_stream(5000, seed=21)
    return IGMM(6, sigma_init=SIG6, max_components=6, overflow=overflow).partial_fit(X)


def test_save_load_round_trip(tmp_path):
    model = fitted_model("prune")
    path = model.save(tmp_path / "fm.npz")
    assert path == tmp_path / "fm.npz" and not (tmp_path / "fm.npz.tmp").exists()
    with np.load(path, allow_pickle=False) as npz:  # plain arrays only: no pickle needed
        assert all(npz[k].dtype != object for k in npz.files)
    loaded = IGMM.load(path)
    _, S = porridge_stream(200, seed=22)
    np.testing.assert_array_equal(loaded.predict(S, IN6, OUT6), model.predict(S, IN6, OUT6))
    m1, c1 = model.predict_cov(S, IN6, OUT6)
    m2, c2 = loaded.predict_cov(S, IN6, OUT6)
    np.testing.assert_array_equal(m1, m2)
    np.testing.assert_array_equal(c1, c2)
    assert loaded.get_params() == model.get_params()
    assert loaded.n_seen_ == model.n_seen_ and loaded.stats_ == model.stats_
    # learning continues identically
    X, _ = porridge_stream(300, seed=23)
    model.partial_fit(X)
    loaded.partial_fit(X)
    np.testing.assert_array_equal(loaded.covariances_, model.covariances_)
    np.testing.assert_array_equal(loaded.score_samples(X), model.score_samples(X))


def test_dict_round_trip_is_json_safe():
    model = fitted_model()
    data = json.loads(json.dumps(model.state_dict()))
    loaded = IGMM.from_state_dict(data)
    _, S = porridge_stream(100, seed=24)
    np.testing.assert_array_equal(loaded.predict(S, IN6, OUT6), model.predict(S, IN6, OUT6))
    empty = IGMM.from_state_dict(json.loads(json.dumps(IGMM(2, sigma_init=1.0).state_dict())))
    assert empty.n_components_ == 0


def test_corrupted_or_mismatched_files_raise_value_error(tmp_path):
    model = fitted_model()
    good = model.save(tmp_path / "good.npz")
    raw = good.read_bytes()

    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"this is not a model" * 10)
    with pytest.raises(ValueError, match="not a valid IGMM file"):
        IGMM.load(garbage)

    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(raw[: len(raw) // 2])
    with pytest.raises(ValueError, match="not a valid IGMM file"):
        IGMM.load(truncated)

    flipped = bytearray(raw)
    mid = raw.index(b"covariances") + 200
    flipped[mid : mid + 16] = bytes(16)
    (tmp_path / "flipped.npz").write_bytes(bytes(flipped))
    with pytest.raises(ValueError, match="not a valid IGMM file"):
        IGMM.load(tmp_path / "flipped.npz")

    with pytest.raises(ValueError, match="not a valid IGMM file"):
        IGMM.load(tmp_path / "missing.npz")

    pickled = tmp_path / "pickled.npz"
    np.savez(pickled, format=np.array("ccm.igmm"), means=np.array([{"a": 1}], dtype=object))
    with pytest.raises(ValueError, match="not a valid IGMM file"):
        IGMM.load(pickled)

    with np.load(good, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    bad_shape = dict(arrays, means=arrays["means"][:, :5])
    np.savez(tmp_path / "shape.npz", **bad_shape)
    with pytest.raises(ValueError, match="means must have shape"):
        IGMM.load(tmp_path / "shape.npz")

    not_pd = dict(arrays, covariances=-arrays["covariances"])
    np.savez(tmp_path / "notpd.npz", **not_pd)
    with pytest.raises(ValueError, match="not positive definite"):
        IGMM.load(tmp_path / "notpd.npz")

    other = dict(arrays, format=np.array("something.else"))
    np.savez(tmp_path / "other.npz", **other)
    with pytest.raises(ValueError, match="not an IGMM snapshot"):
        IGMM.load(tmp_path / "other.npz")

    params = json.loads(str(arrays["params_json"]))
    bad_params = dict(arrays, params_json=np.array(json.dumps(dict(params, n_features=0))))
    np.savez(tmp_path / "params.npz", **bad_params)
    with pytest.raises(ValueError, match="igmm.n_features"):
        IGMM.load(tmp_path / "params.npz")


# ---------------------------------------------------------------------------------------------
# validation
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "arg"),
    [
        ({"n_features": 0}, "n_features"),
        ({"n_features": 2.5}, "n_features"),
        ({"n_features": True}, "n_features"),
        ({"novelty_chi2_quantile": 0.0}, "novelty_chi2_quantile"),
        ({"novelty_chi2_quantile": 1.0}, "novelty_chi2_quantile"),
        ({"novelty_chi2_quantile": float("nan")}, "novelty_chi2_quantile"),
        ({"sigma_init": 0.0}, "sigma_init"),
        ({"sigma_init": -1.0}, "sigma_init"),
        ({"sigma_init": [1.0, 2.0]}, "sigma_init"),
        ({"sigma_init": [1.0, float("inf"), 1.0]}, "sigma_init"),
        ({"sigma_init": "wide"}, "sigma_init"),
        ({"sigma_init": 1e-4}, "sigma_init"),  # sigma_init**2 < cov_floor
        ({"v_min": 0}, "v_min"),
        ({"v_min": 2.5}, "v_min"),
        ({"sp_min": -1.0}, "sp_min"),
        ({"max_components": 0}, "max_components"),
        ({"max_components": 1}, "max_components"),  # a merge needs two
        ({"cov_floor": 0.0}, "cov_floor"),
        ({"overflow": "drop"}, "overflow"),
    ],
)
def test_bad_arguments_raise_config_error_naming_them(kwargs, arg):
    args = {"n_features": 3, "sigma_init": 1.0, **kwargs}
    with pytest.raises(ConfigError, match=rf"^fm\.{arg}: ") as err:
        IGMM(**args, key="fm")
    assert err.value.key == f"fm.{arg}"


def test_single_component_prune_mode_is_allowed():
    model = IGMM(2, sigma_init=0.1, max_components=1, overflow="prune")
    model.partial_fit([[0.0, 0.0], [5.0, 5.0]])
    np.testing.assert_array_equal(model.means_, [[5.0, 5.0]])


def test_bad_inputs_raise_value_error_and_leave_model_unchanged():
    model = IGMM(3, sigma_init=1.0)
    with pytest.raises(ValueError, match="no components"):
        model.predict([0.0, 0.0], [0, 1], [2])
    with pytest.raises(ValueError, match="no components"):
        model.score_samples([0.0, 0.0, 0.0])
    model.partial_fit(np.zeros((5, 3)))
    snapshot = model.state_dict()
    for bad in (np.zeros(2), np.zeros((4, 2)), np.zeros((2, 2, 3)), "abc"):
        with pytest.raises(ValueError, match=r"^X: "):
            model.partial_fit(bad)
    for bad in ([0.0, np.nan, 1.0], [[0.0, 0.0, 0.0], [np.inf, 0.0, 0.0]]):
        with pytest.raises(ValueError, match=r"^X: .*not finite"):
            model.partial_fit(bad)
    with pytest.raises(ValueError, match=r"^X: "):
        model.fit([[0.0, np.nan, 0.0]])
    with pytest.raises(ValueError, match=r"^X: "):
        model.score_samples([np.nan, 0.0, 0.0])
    assert model.state_dict() == snapshot
    with pytest.raises(ValueError, match=r"^x_in: "):
        model.predict([0.0, 0.0, 0.0], [0, 1], [2])
    with pytest.raises(ValueError, match=r"^x_in: .*not finite"):
        model.predict([0.0, np.nan], [0, 1], [2])
    for in_idx, out_idx, arg in (
        ([0, 3], [2], "in_idx"),
        ([0, 0], [2], "in_idx"),
        ([], [2], "in_idx"),
        ([0.5, 1.0], [2], "in_idx"),
        ([0, 1], [-1], "out_idx"),
        ([0, 1], [1], "overlap"),
    ):
        with pytest.raises(ValueError, match=arg):
            model.predict([0.0, 0.0], in_idx, out_idx)
    with pytest.raises(ValueError, match="covariances"):
        gmr_predict([1.0], np.zeros((1, 3)), np.zeros((1, 3)), [0.0], [0], [1])
    with pytest.raises(ValueError, match="not positive definite"):
        gmr_predict([1.0], np.zeros((1, 2)), np.zeros((1, 2, 2)), [0.0], [0], [1])
    with pytest.raises(ValueError, match="not positive definite"):
        GMRConditional([1.0], np.zeros((1, 2)), np.zeros((1, 2, 2)), [0], [1])
    with pytest.raises(ValueError, match="weights"):
        gmr_predict([-1.0], np.zeros((1, 2)), np.eye(2)[None], [0.0], [0], [1])


def test_non_contiguous_and_readonly_inputs():
    X, S = porridge_stream(500, seed=30)
    a = IGMM(6, sigma_init=SIG6).partial_fit(np.asfortranarray(X))
    ro = X.copy()
    ro.setflags(write=False)
    b = IGMM(6, sigma_init=SIG6).partial_fit(ro)
    np.testing.assert_array_equal(a.means_, b.means_)
    s = np.repeat(S, 2, axis=1)[:, ::2]  # strided view of S
    np.testing.assert_array_equal(a.predict(s[5], IN6, OUT6), a.predict(S[5], IN6, OUT6))
