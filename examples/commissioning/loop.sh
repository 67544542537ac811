#!/bin/sh
# The whole commissioning loop of docs/commissioning.md against `distctrl serve` on AMS/TCP port $PORT
# (default 49150, so that a TwinCAT router on 48898 does not matter): excite, serve, record, identify,
# tune, write, check, restore. Run it in a copy of this folder:
#   cp -r examples/commissioning /tmp/cl && cd /tmp/cl && sh loop.sh
# The served CNC has the axes X Y Z: Z is axis_id 3 (--axis Z=3). tests/client/test_loop_example.py runs
# this file as it is.
set -e
trap 'kill $SERVE 2> /dev/null || true' EXIT                    # a failed step leaves no server behind
PORT=${PORT:-49150}
A="--ads 127.0.0.1.1.1 --ip 127.0.0.1 --port $PORT"

# 1. excite: the program for identify (distance control off, within the axis's limits, above the sheet)
distctrl excite --axis Z --work 31.5 --safe 40 --min 25 --max 50 --v-max 300 --a-max 20000 \
    --steps 0.3 --step-count 4 --chirp 1-150 --chirp-seconds 2 --amplitude 0.04 \
    --ramp 31.0:32.0 --ramp-speed 0.5 --large-step 2 --surface 30 --out excite.nc
(echo '#TIME 8'; grep -v '^%' excite.nc) > excite_served.nc     # 8 s to start the recording

# 2. serve the machine running it, and wait until it answers
distctrl serve plant.toml --port $PORT --no-discovery --duration 120 & SERVE=$!
until distctrl machine show $A --axis Z=3 > /dev/null 2>&1; do kill -0 $SERVE; sleep 0.5; done

# 3. record the excitation (exit code 4 if the machine stops sending before the 30 s are up)
distctrl machine record $A --axis Z=3 --seconds 30 --signals command,actual,sensor --out excite_rec.csv
kill $SERVE; wait $SERVE || true

# 4. identify the twin; the reference pass is the job to tune on
distctrl identify excite_rec.csv --command Z.command --actual Z.actual --sensor Z.sensor \
    --actual-sampled start --surface 30 --template reference.toml --out fitted/

# 5. tune on the twin (a short budget; the default 400 sets search longer): tuned/report.txt says
#    whether the set tracks better than the current one, and why not when it does not
distctrl tune fitted/fitted.toml --budget 40 --local --no-robustness --out tuned/ --json > tuned.json

# 6. the machine again, now running its job (job.nc: the reference pass, 2 s off between passes)
distctrl serve job.toml --port $PORT --no-discovery --duration 300 & SERVE=$!
until distctrl machine show $A --axis Z=3 > /dev/null 2>&1; do kill -0 $SERVE; sleep 0.5; done
distctrl machine record $A --axis Z=3 --seconds 8 --signals deviation,state --out before.csv   # tracking before

# 7. write: tuned-objects.lis is the best evaluated set that keeps the machine's filter (all of it is
#    writable over the CNC objects); an older tune writes only tuned.lis
L=tuned/tuned-objects.lis; [ -f "$L" ] || L=tuned/tuned.lis
distctrl machine write $A --axis Z=3 "$L"                   # the dry run: old -> new
distctrl machine write $A --axis Z=3 "$L" --yes --pending   # the job runs: the values wait for its next ON
distctrl machine show $A --axis Z=3                         # in effect, and written/pending

# 8. check: the passes that start after the write run with the new values
distctrl machine record $A --axis Z=3 --seconds 8 --signals deviation,state --out after.csv    # tracking after
distctrl machine show $A --axis Z=3                         # the new values in effect

# 9. restore the values from before (the backup's first line has this command), and look again after the next ON
B=$(ls tuned/*.backup-axis-Z*.lis | head -1)
distctrl machine write $A --axis Z=3 "$B" --yes --pending
sleep 8                                                     # a pass is 3.8 s: its next ON comes
distctrl machine show $A --axis Z=3                         # the old values in effect again
kill $SERVE; wait $SERVE || true
