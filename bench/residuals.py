"""``uav-energy residuals`` against the amount of data: 1×, 4× and 16× the flight time.

The data are simulated 5-minute mixed flights (turns, climbs, speed changes) of the built-in
vehicle with a hidden 5 m/s wind, each with its own seed: 1, 4 and 16 of them. Prints the CPU
time of the analysis (``analyze``: candidate fits, held-out scoring, the k-NN attribution) and
of the attribution alone, per size, and the ratio to the 1× time: linear in the data means
about 4 and 16. CPU time (not wall) because the analysis is single-threaded and the machine may
be shared. An untimed 1× run first takes the first-call costs (lazy imports, caches).
Run: ``python -m bench.residuals``.
"""

from __future__ import annotations

import sys
import time

from estimator.analysis import residual_attribution, residuals
from estimator.analysis.residuals import analyze
from estimator.logs import FlightSeries, flights_from_stream, iter_samples
from estimator.physics.effects import Wind
from estimator.physics.vehicle import default_vehicle
from estimator.sim.files import write_tlog
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate

FLIGHT_S = 300.0
SIZES = (1, 4, 16)
WIND = Wind(speed_mps=5.0, from_deg=60.0)


def simulated_flights(count: int, directory: str) -> list[FlightSeries]:
    """``count`` simulated flights (seeds 1…count), read back from their tlogs."""
    flights = []
    for seed in range(1, count + 1):
        run = simulate(SimConfig(plan="mixed", duration_s=FLIGHT_S, seed=seed, effects=(WIND,)))
        path = write_tlog(run, f"{directory}/flight{seed}.tlog", truth_csv=False)
        flights.extend(flights_from_stream(iter_samples(path), f"flight{seed}"))
    return flights


def main() -> int:
    import tempfile

    attribute = residual_attribution.attribute
    spent = [0.0]

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        start = time.process_time()
        try:
            return attribute(*args, **kwargs)
        finally:
            spent[0] += time.process_time() - start

    residuals.attribute = counted  # time the attribution inside analyze
    print(f"bench residuals: {FLIGHT_S:.0f} s simulated flights, hidden wind; CPU seconds")
    base: float | None = None
    with tempfile.TemporaryDirectory() as tmp:
        everything = simulated_flights(max(SIZES), tmp)
        analyze(everything[:1], default_vehicle())  # warm-up: first-call costs are not size
        for size in SIZES:
            flights = everything[:size]
            spent[0] = 0.0
            start = time.process_time()
            result = analyze(flights, default_vehicle())
            elapsed = time.process_time() - start
            base = base or elapsed
            named = ", ".join(s.label for s in result.selected) or "nothing"
            print(
                f"  {size:2d}× ({sum(len(f) for f in flights):6d} rows)  analyze {elapsed:6.2f} s"
                f"  (×{elapsed / base:5.1f})  attribution {spent[0]:5.2f} s   named: {named}",
                flush=True,
            )
    residuals.attribute = attribute
    return 0


if __name__ == "__main__":
    sys.exit(main())
