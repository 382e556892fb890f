#!/bin/bash
# Runs the checks of tools/README-reference-lights.md; outputs in ${OUT:-/tmp/reference-lights-checks}.
# usage (from /work/main): bash tools/reference-lights-cases/run_checks.sh
set -e
PY=/tmp/refvenv/bin/python
C=tools/reference-lights-cases
O=${OUT:-/tmp/reference-lights-checks}
mkdir -p $O
run() {  # name case accuracy [options...]
    local name=$1 case=$2 acc=$3; shift 3
    echo "== $name: reference_lights.py $C/$case.obj $C/$case.pts $O/$name.txt --accuracy $acc $*"
    /usr/bin/time -f "   wall %e s" $PY tools/reference_lights.py $C/$case.obj $C/$case.pts $O/$name.txt \
        --accuracy $acc -q "$@"
    [ $case = cornell_point ] || $PY $C/check_cases.py $case $O/$name.txt "$@"
}
run 1_point floor_point low
run 2_spot floor_spot low
run 3_sun floor_sun low
run 4a_uniform floor_open low --sky uniform --sky-illuminance 10000
run 4a_overcast floor_open low --sky overcast --sky-illuminance 10000
run 4a_clear_sun floor_open low --sky clear --sky-illuminance 12000 --sun 35 120 80000
run 4b_skylight skylight_room medium --sky overcast --sky-illuminance 10000
run 4b_skylight_fine skylight_room medium --sky overcast --sky-illuminance 10000 --sky-rays 262144
run 4d_bigfloor_uniform big_floor medium --sky uniform --sky-illuminance 10000
run 4d_bigfloor_overcast big_floor medium --sky overcast --sky-illuminance 10000
run 4d_bigfloor_clear big_floor medium --sky clear --sky-illuminance 12000 --sun 35 120 0
run 5_cornell cornell_point medium
# cross-checks with Radiance's own ambient calculation (independent of the path loop)
echo "== 6a: skylight_room_white, clear sky + sun, paths 16384/point vs rtrace -ab 64 -ad 32768"
S="--sky clear --sky-illuminance 15000 --sun 60 200 70000"
/usr/bin/time -f "   wall %e s" $PY tools/reference_lights.py $C/skylight_room_white.obj $C/skylight_room_white.pts \
    $O/6a.txt --paths 16384 $S -q --keep $O/k6a
/usr/bin/time -f "   wall %e s" $PY $C/ambient_check.py $O/k6a $C/skylight_room_white.obj $C/skylight_room_white.pts $O/6a.txt --ad 32768
echo "== 6b: cornell_point (60 points), high vs rtrace -ab 64 -ad 4096"
head -60 $C/cornell_point.pts > $O/c60.pts
/usr/bin/time -f "   wall %e s" $PY tools/reference_lights.py $C/cornell_point.obj $O/c60.pts $O/6b.txt --accuracy high -q --keep $O/k6b
/usr/bin/time -f "   wall %e s" $PY $C/ambient_check.py $O/k6b $C/cornell_point.obj $O/c60.pts $O/6b.txt --ad 4096
