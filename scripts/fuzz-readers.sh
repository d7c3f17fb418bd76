#!/usr/bin/env bash
# A long fuzz run of the file readers, outside CI: the properties of
# crates/cellist-io/tests/fuzz_readers.rs (no panic, no hang, no allocation beyond
# the input's size, errors that name the file and an existing line, finite values
# in what is accepted) with many more cases than `cargo test` runs, in rounds of a
# fresh random seed each, until DURATION seconds have passed.
#
#   scripts/fuzz-readers.sh [DURATION_SECONDS]      (default 600)
#   PROPTEST_CASES=N scripts/fuzz-readers.sh        (cases per property per round,
#                                                    default 200000)
#
# One test thread, so that a 2-core machine keeps a core for other work. A failure
# prints the round's seed (rerun it with PROPTEST_RNG_SEED=<seed>) and the minimal
# failing input as a byte-string literal: fix the reader and add the input to
# crates/cellist-io/tests/fuzz-corpus/<reader>/ (see the README there).
#
# Coverage-guided fuzzers are not used: cargo-fuzz (libFuzzer) needs a nightly
# compiler and this project builds on stable only; cargo-afl runs on stable but
# needs AFL++ built and installed (`cargo install cargo-afl`, `cargo afl
# config --build`) and a separate harness crate, which no machine of this project
# sets up. These random and mutational properties are the long run.
set -euo pipefail
cd "$(dirname "$0")/.."

duration=${1:-600}
cases=${PROPTEST_CASES:-200000}
cargo test --release -p cellist-io --test fuzz_readers --no-run

end=$((SECONDS + duration))
round=0
while ((SECONDS < end)); do
    round=$((round + 1))
    seed=$(od -An -N4 -tu4 /dev/urandom | tr -d ' ')
    start=$SECONDS
    echo "round $round: PROPTEST_RNG_SEED=$seed PROPTEST_CASES=$cases"
    if ! PROPTEST_RNG_SEED=$seed PROPTEST_CASES=$cases \
        cargo test --release -p cellist-io --test fuzz_readers -q -- --test-threads=1; then
        echo "round $round (PROPTEST_RNG_SEED=$seed) FAILED after $SECONDS s: fix the reader," \
            "then add the minimal failing input to crates/cellist-io/tests/fuzz-corpus/<reader>/"
        exit 1
    fi
    echo "round $round passed in $((SECONDS - start)) s"
done
echo "done: $round round(s) of $cases cases per property in $SECONDS s, no failure"
