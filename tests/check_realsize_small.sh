#!/usr/bin/env bash
# The real-size calls at DVS_REALSIZE_SCALE=small (every real width and channel count, few pixels and tokens: the
# 128-, 256- and 512-channel VAE convolutions, the transformer's 3072-wide GEMMs) by value against their CPU
# references, and their measured device memory against the plan: what stage d of the device script measures at the
# real size, checked here at every commit so that a device minute is never spent on a broken bench.
#   tests/check_realsize_small.sh CALLS DVS_BENCH [RUNNER...]
# CALLS: DVS_REALSIZE_CALLS (e.g. vae_encode,vae_decode); RUNNER: a command the bench runs under (e.g.
# tests/run_on_mesa_coopmat.sh). Fails unless every call printed its JSON line with max_abs_err within its tolerance
# and its peak within the plan plus 1 MiB (allocation alignments).
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: tests/check_realsize_small.sh CALLS DVS_BENCH [RUNNER...]" >&2
  exit 2
fi
calls="$1" bench="$2"
shift 2
log="$(mktemp)"
trap 'rm -f "$log"' EXIT
DVS_REALSIZE_SCALE=small DVS_REALSIZE_CALLS="$calls" "$@" "$bench" --filter realsize > "$log" 2>&1 ||
  { cat "$log"; echo "check_realsize_small.sh: dvs-bench failed" >&2; exit 1; }
cat "$log"
rc=0
field() { sed -E "s/.*\"$1\":(\"[^\"]*\"|[^,}]*).*/\1/" <<< "$2"; }
for call in ${calls//,/ }; do
  # One line per call (the transformer's: one per batch size, realsize_transformer_b2 and _b1).
  lines="$(grep -E "^\{.*\"op\":\"realsize_${call}(_b[0-9]+)?\"" "$log" || true)"
  if [ -z "$lines" ]; then
    echo "check_realsize_small.sh: no result line for realsize_${call}" >&2
    rc=1
    continue
  fi
  while IFS= read -r line; do
    e="$(field max_abs_err "$line")" t="$(field tolerance "$line")" p="$(field peak_bytes "$line")" q="$(field plan_bytes "$line")"
    if ! awk -v e="$e" -v t="$t" -v p="$p" -v q="$q" \
         'BEGIN { exit !(e != "null" && e + 0 <= t + 0 && t + 0 > 0 && p + 0 <= q + 1048576 && q + 0 > 0) }'; then
      echo "check_realsize_small.sh: $(field op "$line"): max_abs_err $e (tolerance $t), peak $p B (plan $q B)" >&2
      rc=1
    fi
  done <<< "$lines"
done
[ "$rc" -eq 0 ] && echo "check_realsize_small.sh: ${calls}: every value within its tolerance, every peak within its plan"
exit "$rc"
