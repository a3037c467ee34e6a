#!/usr/bin/env bash
# TacDiff training recipe for one GPU machine (made the 0.6 models; see MODEL_CARD_tacdiff.md).
#
# Renders simulated pairs and painted pairs from real markerless frames (one folder per sensor,
# with markers.json: `python benches/export_paint_frames.py DIR` writes Taxim's training presses),
# then trains three runs side by side on the GPU within a wall-clock budget:
#   default: the shipped default model's weights, x0-L1 loss, simulated + painted real pairs
#   fast:    the shipped fast model's weights, v-MSE loss, the same pairs
#   simonly: like default on the simulated pairs only (the ablation: what the real texture adds)
# and copies the final EMA weights, two snapshots and the logs to OUT_DIR.
#
# Usage: bash benches/gpu_train_tacdiff.sh PAINT_DIR OUT_DIR [TOTAL_SECONDS]
# Sizes and device can be overridden for a dry run on a CPU: SIM, PAINT_PAIRS, BATCH, DEVICE,
# WORKERS (render processes), THREADS (batch threads per run), TACSWITCH (the command); RUNS
# picks runs (default "default fast simonly"), FAST_LOSS the fast run's loss (default v_mse).
set -euo pipefail
PAINT=${1:?PAINT_DIR}
OUTD=${2:?OUT_DIR}
TOTAL=${3:-480}
SIM=${SIM:-1200}
PAINT_PAIRS=${PAINT_PAIRS:-600}
BATCH=${BATCH:-48}
DEVICE=${DEVICE:-cuda}
WORKERS=${WORKERS:-15}
THREADS=${THREADS:-5}
TS=${TACSWITCH:-python3 -m tacswitch}
RUNS=${RUNS:-default fast simonly}
FAST_LOSS=${FAST_LOSS:-v_mse}
WORK=${WORK:-/tmp/tacdiff_gpu}
mkdir -p "$OUTD" "$WORK/simonly"

$TS train tacdiff --data "$WORK/pairs" --simulate "$SIM" --paint "$PAINT/gelsight" \
    --paint "$PAINT/gelsight_mini" --paint-pairs "$PAINT_PAIRS" --workers "$WORKERS" --seed 6 \
    --render-only -q
echo "rendered in $SECONDS s: $(ls "$WORK/pairs" | wc -l) shards"
for f in "$WORK"/pairs/pairs_*.npz; do
    case $(basename "$f") in pairs_painted*) ;; *) ln -sf "$f" "$WORK/simonly/" ;; esac
done

# Loading the shards and exporting take about a minute; the rest is training.
BUDGET=$((TOTAL - SECONDS - 75))
echo "training budget: $BUDGET s"
if [ "$BUDGET" -lt 30 ]; then echo "TOTAL_SECONDS: rendering left under 30 s to train" >&2; exit 2; fi
common=(--terminal-fraction 0.9 --crop 96 --lr 2e-4 --warmup 200 --steps 1000000
        --time-budget "$BUDGET" --save-every 1000000 --snapshot-every 500 --device "$DEVICE" --threads 2
        --workers $((THREADS + 1)) --batch "$BATCH" --seed 6 -q)
case " $RUNS " in *" default "*)
$TS train tacdiff --data "$WORK/pairs" --init default --loss x0_l1 --out "$WORK/default" \
    "${common[@]}" > "$WORK/default.txt" 2>&1 & ;; esac
case " $RUNS " in *" fast "*)
$TS train tacdiff --data "$WORK/pairs" --init fast --loss "$FAST_LOSS" --out "$WORK/fast" \
    "${common[@]}" > "$WORK/fast.txt" 2>&1 & ;; esac
case " $RUNS " in *" simonly "*)
$TS train tacdiff --data "$WORK/simonly" --init default --loss x0_l1 --out "$WORK/simonly_run" \
    "${common[@]}" > "$WORK/simonly.txt" 2>&1 & ;; esac
status=0
for job in $(jobs -p); do wait "$job" || status=1; done
echo "trained in $SECONDS s (status $status)"

# Final weights of each run; for default also the snapshots at about 1/2 and 3/4 of its steps.
cp "$WORK/default/model.safetensors" "$OUTD/default_final.safetensors" || true
cp "$WORK/fast/model.safetensors" "$OUTD/fast_final.safetensors" || true
cp "$WORK/simonly_run/model.safetensors" "$OUTD/simonly_final.safetensors" || true
mapfile -t snaps < <(ls "$WORK/default"/ema_step*.safetensors 2>/dev/null || true)
n=${#snaps[@]}
if [ "$n" -ge 2 ]; then
    cp "${snaps[$((n / 2))]}" "$OUTD/default_$(basename "${snaps[$((n / 2))]}")"
    cp "${snaps[$((3 * n / 4))]}" "$OUTD/default_$(basename "${snaps[$((3 * n / 4))]}")"
fi
mapfile -t fsnaps < <(ls "$WORK/fast"/ema_step*.safetensors 2>/dev/null || true)
n=${#fsnaps[@]}
if [ "$n" -ge 2 ]; then
    cp "${fsnaps[$((n / 2))]}" "$OUTD/fast_$(basename "${fsnaps[$((n / 2))]}")"
    cp "${fsnaps[$((3 * n / 4))]}" "$OUTD/fast_$(basename "${fsnaps[$((3 * n / 4))]}")"
fi
tail -n 3 "$WORK"/*.txt > "$OUTD/logs.txt" 2>&1 || true
for r in default fast simonly_run; do
    echo "== $r" >> "$OUTD/logs.txt"; cat "$WORK/$r/log.jsonl" >> "$OUTD/logs.txt" 2>/dev/null || true
done
ls -la "$OUTD"
exit $status
