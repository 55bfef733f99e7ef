#!/bin/sh
# Fit the power model to the real datasets; writes out/fit/vehicles/*.toml, out/fit/*/ reports
# and out/fit/*.json, and says which fitted vehicle files differ from the tracked ones in
# config/vehicles (which it never writes: copy a file there to adopt its fit).
# Usage: scripts/fit_real.sh [DATA_DIR] (default ../shared/data). Results and assumptions:
# docs/fit.md.
set -eu
DATA=${1:-../shared/data}
FIT=${UAV_ENERGY:-.venv/bin/uav-energy}
VEHICLES=out/fit/vehicles
mkdir -p out/fit "$VEHICLES"
IRIS="$DATA/iris_quadcopter_logs"
PRIORS_NOTE="Data cover 0-6 m/s: hover power is measured; tip speed and profile share come from the priors."

$FIT fit "$IRIS"/2016-03-*/*/*.log --title "IRIS+ March 2016" \
  --name iris-plus-2016-03 --mass-kg 1.282 --capacity-ah 5.1 --cells 3 \
  --note "3DR IRIS+ (APM:Copter 3.3), the March 2016 flights of kevinaangstadt/quadcopter-logs" \
  --note "(../shared/data/iris_quadcopter_logs, see its SOURCE.md), fitted by scripts/fit_real.sh." \
  --note "mass_kg: 3DR's published IRIS+ weight with battery, 1282 g (ASSUMED: mass is not in the logs)." \
  --note "battery: BATT_CAPACITY = 5100 mAh, 3S LiPo (mav.parm)." \
  --note "$PRIORS_NOTE" \
  --out "$VEHICLES/iris_plus_2016_03.toml" --report out/fit/iris_2016_03 \
  --json > out/fit/iris_2016_03.json

$FIT fit "$IRIS"/2016-0[678]-*/*/*.log --title "IRIS+ June-August 2016" \
  --name iris-plus-2016-06-08 --mass-kg 1.58 --capacity-ah 5.1 --cells 3 \
  --note "3DR IRIS+ (APM:Copter 3.3), the June-August 2016 flights of kevinaangstadt/quadcopter-logs" \
  --note "(../shared/data/iris_quadcopter_logs, see its SOURCE.md), fitted by scripts/fit_real.sh." \
  --note "mass_kg 1.58 is an ESTIMATE: hover power rose from 151 W (March) to 207 W with no recorded" \
  --note "change; momentum theory (hover power ~ m^1.5) gives 1.282 kg * (207/151)^(2/3) = 1.58 kg." \
  --note "battery: BATT_CAPACITY = 5100 mAh, 3S LiPo (mav.parm)." \
  --note "$PRIORS_NOTE" \
  --out "$VEHICLES/iris_plus_2016_06_08.toml" --report out/fit/iris_2016_06_08 \
  --json > out/fit/iris_2016_06_08.json

$FIT fit "$DATA"/cmu_m100_subset/*.csv --title "CMU DJI Matrice 100 (8 flights)" \
  --name dji-m100-cmu --mass-kg 2.355 --capacity-ah 4.5 --cells 6 \
  --note "DJI Matrice 100, the 8-flight CMU validation subset (doi:10.1184/R1/12683453;" \
  --note "../shared/data/cmu_m100_subset, see its SOURCE.md), fitted by scripts/fit_real.sh." \
  --note "mass_kg: DJI's published M100 weight with TB47D battery, 2355 g, WITHOUT the CMU instruments" \
  --note "(anemometer, INS, Raspberry Pi: mass not documented). The model is for no package: flights" \
  --note "with 250/500 g were fitted rescaled to 2.355 kg + payload (c3 ~ m^1.5, c4 ~ m)." \
  --note "battery: TB47D 4.5 Ah 6S (dataset README). Power is the dataset's V*I column y." \
  --note "slow_error_fraction: the residual's 10 s means scatter by 13-30 W (3-7 % of hover) with" \
  --note "the payload and the anemometer's wind put in (estimator/estimation/online_effects.py)." \
  --note "[effects.heave]: the thrust of a vertical acceleration at eq. (2)'s gain 1, not fitted: the" \
  --note "climbs' ends and the turnarounds' height recovery read as mass steps without it (the" \
  --note "online tracker, docs/residuals.md); the residual loop names it on 3 of the 8 flights." \
  --slow-error-fraction 0.05 --heave-gain 1.0 \
  --out "$VEHICLES/dji_m100_cmu.toml" --report out/fit/cmu_m100 \
  --json > out/fit/cmu_m100.json

for fitted in "$VEHICLES"/*.toml; do
  tracked=config/vehicles/${fitted##*/}
  if cmp -s "$fitted" "$tracked"; then
    echo "$fitted: the same as $tracked"
  else
    echo "$fitted: differs from $tracked (diff them; copy it there to adopt the fit)"
  fi
done
