"""Buffer layout of the IGMM kernels (:mod:`ccm.learn.mixtures._igmm_kernels`, and the GMR
kernels of :mod:`ccm.learn.mixtures._gmr_kernels` that read the same buffers).

Mixture buffers (``Kmax`` = ``max_components``, ``d`` = ``n_features``); only the first
``K = istate[I_K]`` slots are live, in creation order:

* ``means`` (Kmax, d); ``covs`` (Kmax, d, d); ``chols`` (Kmax, d, d), lower Cholesky factors
  of ``covs`` with zeros above the diagonal;
* ``comp`` (N_COMP, Kmax) per-component scalars: ``comp[C_LOGDET]`` log det C_j,
  ``comp[C_SP]`` accumulated posterior support sp_j, ``comp[C_AGE]`` updates since creation
  v_j, ``comp[C_STAMP]`` a number that changes whenever mu_j, C_j or sp_j change (unique over
  the model's life, so it also tells a moved or replaced slot apart). All float64; counts
  are exact up to 2**53;
* ``istate`` int64 counters (``I_*``), ``params`` float64 settings (``P_*``).

Change stamps let the update skip refactorising covariances that did not change bitwise and
let a GMR cache refresh only the components that changed: with K = 20 most components have
a posterior so small that the update leaves them bit-for-bit as they were. Skipping is exact.
"""

from __future__ import annotations

# istate slots
I_K = 0  # live components
I_SEEN = 1  # points processed
I_VERSION = 2  # bumped on every model change (GMR caches compare against it)
I_CREATED = 3  # components created by the novelty test
I_MERGED = 4  # overflow merges
I_OVERFLOW_PRUNED = 5  # components dropped on overflow (overflow="prune")
I_SUPPORT_PRUNED = 6  # components removed by the v > v_min and sp < sp_min rule
I_JITTER = 7  # factorisations that needed extra diagonal loading (numerical safety net)
I_STAMP = 8  # last change stamp handed out
N_ISTATE = 9

# params slots
P_THRESHOLD = 0  # squared Mahalanobis novelty threshold (chi-square quantile)
P_FLOOR = 1  # covariance eigenvalue floor
P_SP_MIN = 2
P_V_MIN = 3
P_OVERFLOW = 4  # 0: merge, 1: prune
N_PARAMS = 5

OVERFLOW_MERGE = 0
OVERFLOW_PRUNE = 1

# comp rows
C_LOGDET = 0
C_SP = 1
C_AGE = 2
C_STAMP = 3
N_COMP = 4
