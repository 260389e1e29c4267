"""The long fuzz campaign: malformed inputs per reader, counts per outcome.

Each input runs in a worker process with an address-space limit (4 GiB by
default) and a time limit; see :mod:`evedge._fuzz`. Prints a table of counts
per target and outcome and the failing cases (target, case, mutation, detail).

    .venv/bin/python benchmarks/fuzz_campaign.py --cases 10000
    .venv/bin/python benchmarks/fuzz_campaign.py --targets hdf5,mat --cases 500 --seed 3
"""

from __future__ import annotations

import argparse
import time

from tqdm import tqdm

from evedge._fuzz import OUTCOMES, TARGETS, Limits, Tally, run


def _table(tally, title: str) -> str:
    lines = [title, f"{'target':<13}" + "".join(f"{o:>10}" for o in OUTCOMES)]
    for target, per in tally.counts.items():
        lines.append(f"{target:<13}" + "".join(f"{per[o]:>10}" for o in OUTCOMES))
    lines.append(f"{'total':<13}" + "".join(f"{tally.total(o):>10}" for o in OUTCOMES))
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", type=int, default=2000, help="cases per target")
    ap.add_argument("--targets", default=",".join(TARGETS), help="comma-separated (default: all)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--memory-gib", type=float, default=4.0, help="address-space limit per worker")
    ap.add_argument("--time-s", type=float, default=20.0, help="time limit per case")
    ap.add_argument("--show", type=int, default=40, help="failing cases to list")
    ap.add_argument("--checkpoint", default=None, metavar="FILE",
                    help="rewrite the counts so far into FILE every 500 cases (a long run can be read while it runs)")
    args = ap.parse_args()
    targets = [t for t in args.targets.split(",") if t]
    start = time.monotonic()
    partial = Tally()

    def progress(result):
        bar.update()
        partial.add(result)
        if args.checkpoint and partial.total() % 500 == 0:
            with open(args.checkpoint, "w") as fh:
                fh.write(_table(partial, f"{partial.total()} cases so far, {time.monotonic() - start:.0f} s"))

    with tqdm(total=args.cases * len(targets), unit="case") as bar:
        tally = run(targets, args.cases, args.seed, Limits(int(args.memory_gib * 2**30), args.time_s),
                    progress=progress)
    print("\n" + _table(tally, f"{tally.total()} cases, seed {args.seed}, {args.memory_gib:g} GiB address space, "
                               f"{args.time_s:g} s per case; {time.monotonic() - start:.0f} s wall"))
    for r in tally.failures[: args.show]:
        print(f"{r.outcome:>9} {r.case_id} [{r.mutation[:70]}] {r.detail[:200]}")


if __name__ == "__main__":
    main()
