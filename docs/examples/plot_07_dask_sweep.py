"""
A sweep on a Dask cluster
=========================

``exo-bench bench --full`` and ``exo-bench stability --full`` run their work as tasks on Dask distributed: a
local cluster of single-threaded worker processes by default, or a running one (``--scheduler ADDRESS``). Your
own sweep is a function submitted once per task. Here: two local workers check, on seeded random trees of 2 to
40 links, that ``newton-euler`` and ``matrix-factored`` agree, one tree per task. The workers are threads of
this process (``processes=False``), so the example starts quickly inside the docs build; with worker processes
(``processes=True``, what the project's sweeps use), a script needs the ``if __name__ == "__main__":`` guard,
as each worker imports the main module again.
"""


def agreement(nlinks: int, seed: int) -> tuple[int, float]:
    """One task: the largest relative difference of the two methods' forces on a random 3D tree."""
    import numpy as np

    from exo_bench import prepare, presets, random_states

    mech = presets.random_tree(nlinks, dim=3, seed=seed)
    q, qd, qdd = random_states(mech, 200, seed=seed)
    a = prepare(mech, "newton-euler").inverse_dynamics(q, qd, qdd)
    b = prepare(mech, "matrix-factored").inverse_dynamics(q, qd, qdd)
    return nlinks, float(np.abs(a - b).max() / np.abs(b).max())


if __name__ == "__main__":
    from distributed import Client, LocalCluster

    sizes = [2, 5, 10, 20, 40]
    with (
        LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as lc,
        Client(lc) as client,
    ):
        print("workers:", len(client.scheduler_info()["workers"]))
        futures = [client.submit(agreement, n, seed) for seed, n in enumerate(sizes)]
        results = client.gather(futures)
    for n, difference in results:
        print(f"{n:3d} links: newton-euler vs matrix-factored {difference:.1e}")
    assert all(d < 1e-12 for _, d in results)
