#!/bin/bash
# The must-show of issue 35 on ../shared/data/uav_real_copr (41 photos, no
# EXIF GNSS, ODM's gcp_list.txt), doc/real_surfaces.md:
#
#  1. process_flight on the whole block with the published control
#     (--gcp-sigma 1: handheld GNSS coordinates) -> full/: the dense step's
#     time and memory on a real block, and camera centres that stand in for
#     the GNSS copr's photos lack;
#  2. the block split into two flights of the same day (1st, 3rd, ... photo:
#     "odd"; 2nd, 4th, ...: "even"), each given its photos' centres from 1.
#     as a geo.txt with 0.5 m of seeded noise per photo (a receiver), the
#     even one shifted by SHIFT_E, SHIFT_N, SHIFT_U metres (a consumer
#     receiver's offset), and each oriented on its own from its own tie
#     points and these positions (process_flight --geo);
#  3. the even flight co-registered to the odd one's DEM (--reference) and
#     its DoD written: the shift found, median dz and % flagged on stable
#     ground (no change happened: everything is stable);
#  4. the change stage alone, again, with one global LoD and the error
#     model's two bin spreads side by side (bench_flight_change, built by
#     `cmake --build ... --target bench_flight_change`; skipped when absent):
#     `bench_flight_change WORK/out_odd/flight_1/surface_e01.tif
#     WORK/out_even/flight_1/surface_e01.tif` redoes it in seconds on an
#     earlier run's DEMs without orienting the flights again.
#
#   bench/real_flight_change/run.sh [WORK] [SHIFT_E] [SHIFT_N] [SHIFT_U] [WORKING_SIZE]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
data="$repo/../shared/data/uav_real_copr"
work=${1:-/tmp/real_flight_change}
shift_e=${2:-3.0}
shift_n=${3:--2.0}
shift_u=${4:-1.0}
size=${5:-1100}
. "$repo/scripts/lib.sh"
tool="$SM_WS/devel/lib/slope_monitor/process_flight"
mkdir -p "$work/odd" "$work/even"
run() {  # name, args...
  local name=$1; shift
  rm -rf "$work/out_$name"
  /usr/bin/time -v nice -n 5 "$tool" --threads 2 --working-size "$size" --overwrite --out "$work/out_$name" "$@" \
      > "$work/$name.log" 2> "$work/$name.err" || echo "process_flight ($name): exit $?"
  sed "s/^/$name: /" "$work/$name.log"
  grep -E "Maximum resident|Elapsed" "$work/$name.err" | sed "s/^\s*/$name: /"
}
[ -f "$work/out_full/flight_1/cameras.csv" ] ||
  run full --photos "$data/images" --gcp "$data/gcp_list.txt" --gcp-sigma 1 --no-leave-one-out
i=0
for f in $(ls "$data/images" | sort); do
  half=$([ $((i % 2)) -eq 0 ] && echo odd || echo even)
  ln -sf "$data/images/$f" "$work/$half/$f"
  i=$((i + 1))
done
for half in odd even; do
  python3 - "$work/out_full/flight_1" "$work/$half" "$half" "$shift_e" "$shift_n" "$shift_u" \
      > "$work/geo_$half.txt" <<'PY'
import csv, os, random, sys
full, folder, half = sys.argv[1], sys.argv[2], sys.argv[3]
shift = [float(v) for v in sys.argv[4:7]] if half == "even" else [0.0, 0.0, 0.0]
crs = {}
for l in open(os.path.join(full, "crs.txt")):
    k, _, v = l.partition(":")
    crs[k.strip()] = v.strip()
origin = [float(v) for v in crs["origin"].split()]
rng = random.Random(35 if half == "odd" else 36)
photos = set(os.listdir(folder))
print(crs["crs"])
for row in csv.DictReader(open(os.path.join(full, "cameras.csv"))):
    if row["image"] not in photos:
        continue
    x = [float(row[k]) + o + s + rng.gauss(0.0, 0.5) for k, o, s in zip("xyz", origin, shift)]
    print("%s %.3f %.3f %.3f" % (row["image"], x[0], x[1], x[2]))
PY
done
run odd --photos "$work/odd" --geo "$work/geo_odd.txt"
run even --photos "$work/even" --geo "$work/geo_even.txt" --reference "$work/out_odd"
compare="$SM_WS/build/slope_monitor/bin/bench_flight_change"
if [ -x "$compare" ]; then
  "$compare" "$work/out_odd/flight_1/surface_e01.tif" "$work/out_even/flight_1/surface_e01.tif" |
      tee "$work/flight_change.txt" | grep -v "^  "
fi
