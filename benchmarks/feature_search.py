"""Which kernels make up a point's features, 'nearest' against 'support', on every data set.

    python benchmarks/feature_search.py [--seeds 0] [--fractions 0.8] [--datasets street,...]

'support' (the default profile's) takes every kernel that is not zero at a point, so training,
point queries and grids are one model; 'nearest' (the real-time profile's, the paper's Alg. 3) each
point's nearest clusters (MapConfig.features). Both profiles of `MapConfig.for_resolution` map each
data set's training scans scan by scan, with each setting, in one process, as benchmarks/peers.py
measures them: held-out F1, near F1 against the exact occupancy on the simulated scenes, build
seconds with everything learned, memory and query seconds for every test point. Each map is built
once after an untimed warm-up, so a noisy moment of the machine shows in the ratios.
"""

from __future__ import annotations

import statistics

from common import heading, markdown_table, sweep_arguments
from online_mapping import loaded_datasets
from peers import DATASETS, measure, warm_up
from results_file import run_recorded

FEATURES = ("nearest", "support")
PROFILES = {"default": "ehm", "realtime": "ehm-realtime"}


def pair(values: dict[str, dict], key: str, digits: int, ratio: bool = True) -> str:
    """'nearest / support' of one measure, with the support's ratio where `ratio`."""
    nearest, support = values["nearest"].get(key), values["support"].get(key)
    if nearest is None or support is None:
        return ""
    text = f"{nearest:.{digits}f} / {support:.{digits}f}"
    return f"{text} ({support / nearest:.2f}x)" if ratio else text


def main() -> None:
    sweep = sweep_arguments(__doc__.splitlines()[0], DATASETS, fractions="0.8")
    print(heading("Feature search", f"seeds {sweep.seeds}, train fractions {sweep.fractions}"))
    for features in FEATURES:
        for method in PROFILES.values():
            for dim in (2, 3):
                warm_up(method, dim, {"features": features})
    rows = []
    for name, scans, scene in loaded_datasets(sweep.datasets):
        for fraction in sweep.fractions:
            found: dict[str, dict[str, list[dict]]] = {
                p: {f: [] for f in FEATURES} for p in PROFILES
            }
            for seed in sweep.seeds:
                for features in FEATURES:
                    runs = measure(
                        name,
                        scans,
                        scene,
                        fraction,
                        seed,
                        {"features": features},
                        tuple(PROFILES.values()),
                    )
                    for profile, method in PROFILES.items():
                        found[profile][features].append(runs[method])
            for profile in PROFILES:
                means = {
                    features: {key: statistics.fmean(run[key] for run in runs) for key in runs[0]}
                    for features, runs in found[profile].items()
                }
                rows.append(
                    [
                        name,
                        f"{fraction:.0%}",
                        profile,
                        pair(means, "held-out F1", 4, ratio=False),
                        pair(means, "near F1 (exact)", 4, ratio=False),
                        pair(means, "build s", 2),
                        pair(means, "memory MB", 2),
                        pair(means, "query s", 3),
                    ]
                )
    header = ["data set", "train", "profile", "held-out F1", "near F1", "build s", "memory MB"]
    print("'nearest' / 'support', the support's ratio in brackets.\n")
    print(markdown_table([*header, "query s"], rows, text_columns=3))


if __name__ == "__main__":
    run_recorded(main, __file__)
