#!/usr/bin/env bash
# The output folders of this build against another binary's, file by file: a
# refactor must change no output byte.
#
#   BASELINE=/path/to/older/cellist bash scripts/same-outputs.sh
#   BASELINE=... BASELINE_MPI=/path/to/older/mpi/cellist bash scripts/same-outputs.sh
#   CASES="lj-melt billiards" BASELINE=... bash scripts/same-outputs.sh
#
# Cases: every scenario in examples/ (`cellist run`, 2 threads); the collision
# benchmark's sample input (`billiards run --viz --gif --png --output`, and its
# final state on standard output in bits); the same run stopped at step 10 with
# checkpoints and continued from its checkpoint (`billiards-restart`); the melt
# blowing up (`md-blowup`: its last good frame and checkpoint); and with
# BASELINE_MPI (and Open MPI) `mpirun -np 2 cellist run` of the md melt and the
# pse sine, each with this build's MPI binary (`--features mpi`). CASES picks
# some of them by name. Each case runs with both binaries into folders of their
# own; the script prints `same` or the files that differ (or exist on one side
# only) per case, and exits with 1 if any case differs. Standard output and
# summary.json are not compared (they hold wall times); the other files are.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
: "${BASELINE:?set BASELINE to the cellist binary to compare with}"
target=${CARGO_TARGET_DIR:-$here/target}
work=${WORK:-$(mktemp -d)}
mkdir -p "$work/bin"
echo "outputs in $work"

cargo build --release -q --manifest-path "$here/Cargo.toml" -p cellist-cli
cp "$target/release/cellist" "$work/bin/current"
if [ -n "${BASELINE_MPI:-}" ]; then
    cargo build --release -q --manifest-path "$here/Cargo.toml" -p cellist-cli --features mpi
    cp "$target/release/cellist" "$work/bin/current-mpi"
    # leave target/release/cellist as the plain build
    cargo build --release -q --manifest-path "$here/Cargo.toml" -p cellist-cli
fi

sample="$here/../shared/testdata/billiards/inputs/sample.in"
cases=()
for scenario in "$here"/examples/*.toml; do
    cases+=("$(basename "$scenario" .toml)")
done
cases+=(billiards billiards-restart md-blowup)
[ -n "${BASELINE_MPI:-}" ] && cases+=(mpi-md mpi-pse)
wanted=" ${CASES:-${cases[*]}} "

# run_case NAME BINARY MPI_BINARY FOLDER
run_case() {
    local name=$1 binary=$2 mpi=$3 out=$4
    rm -rf "$out"
    mkdir -p "$out"
    case $name in
        billiards)
            "$binary" billiards run "$sample" --threads 2 --viz "$out/steps.out" \
                --gif "$out/run.gif" --png "$out/final.png" --output "$out/final.out" \
                > "$out.log" 2>&1
            "$binary" billiards run "$sample" --threads 1 --format bits \
                > "$out/final.stdout" 2>> "$out.log"
            ;;
        billiards-restart)
            (cd "$out" \
                && "$binary" billiards run "$sample" --steps 10 --viz steps.out --gif run.gif \
                    --checkpoint state.ckpt --checkpoint-every 5 --output first.out \
                && "$binary" billiards run "$sample" --viz steps.out --gif run.gif \
                    --checkpoint state.ckpt --checkpoint-every 5 --restart state.ckpt \
                    --output final.out) > "$out.log" 2>&1
            ;;
        md-blowup)
            # exits with 3: the last good frame and checkpoint are the outputs
            "$binary" run "$here/examples/lj-melt.toml" --threads 2 --set run.dt=0.5 \
                --set run.steps=50 --out "$out" > "$out.log" 2>&1 || [ $? -eq 3 ]
            ;;
        mpi-md)
            mpirun --allow-run-as-root --oversubscribe -np 2 "$mpi" run \
                "$here/examples/lj-melt.toml" --threads 1 --set run.steps=200 \
                --out "$out" > "$out.log" 2>&1
            ;;
        mpi-pse)
            mpirun --allow-run-as-root --oversubscribe -np 2 "$mpi" run \
                "$here/examples/pse-sine.toml" --threads 1 --out "$out" > "$out.log" 2>&1
            ;;
        *)
            "$binary" run "$here/examples/$name.toml" --threads 2 --out "$out" \
                > "$out.log" 2>&1
            ;;
    esac
}

differ=0
for name in "${cases[@]}"; do
    [[ $wanted == *" $name "* ]] || continue
    run_case "$name" "$BASELINE" "${BASELINE_MPI:-}" "$work/baseline/$name" \
        || echo "$name: the baseline failed (see $work/baseline/$name.log)"
    run_case "$name" "$work/bin/current" "$work/bin/current-mpi" "$work/current/$name" \
        || echo "$name: this build failed (see $work/current/$name.log)"
    if report=$(diff -rq -x summary.json "$work/baseline/$name" "$work/current/$name"); then
        echo "$name: same ($(find "$work/current/$name" -type f | wc -l) files)"
    else
        echo "$name: DIFFERS"
        echo "$report" | sed 's/^/    /'
        differ=1
    fi
done
exit "$differ"
