#!/usr/bin/env bash
# Where a shader's time goes on lavapipe: samples a running command with perf, then disassembles (gdb) the
# hottest pages of the JIT-compiled code, each instruction with its sample count. Lavapipe's machine code has
# no symbols, so this is how one sees, e.g., that every texelFetch is a call or that fma() is a multiply and
# an add.
#
#   bench/profile_jit.sh [--delay S] [--seconds S] [--pages N] [--out DIR] -- COMMAND [ARGS...]
#
# The command must keep the shader busy past delay + seconds, e.g.
#   DVS_BENCH_CONV_LOOP=15 bench/profile_jit.sh -- build/bench/dvs-bench --filter conv
# Writes DIR/annotated.txt (count, address, instruction over the hottest pages) and DIR/summary.txt (samples per
# mnemonic), DIR defaulting to ./jit-profile. Needs perf (Debian: linux-perf) and gdb, and permission to attach
# (root, or kernel.perf_event_paranoid <= 1 and ptrace_scope 0).
set -euo pipefail

delay=5 seconds=3 pages=4 out=jit-profile
while [ $# -gt 0 ]; do
  case "$1" in
    --delay) delay="$2"; shift 2 ;;
    --seconds) seconds="$2"; shift 2 ;;
    --pages) pages="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --) shift; break ;;
    *) echo "profile_jit.sh: unknown option '$1' (usage: see the top of $0)" >&2; exit 2 ;;
  esac
done
[ $# -gt 0 ] || { echo "profile_jit.sh: give the command to profile after --" >&2; exit 2; }
for tool in perf gdb python3; do
  command -v "$tool" > /dev/null || { echo "profile_jit.sh: '$tool' is not installed (apt-get install linux-perf gdb)" >&2; exit 2; }
done
mkdir -p "$out"

"$@" > "$out/command.log" 2>&1 &
pid=$!
sleep "$delay"
kill -0 "$pid" 2> /dev/null || { echo "profile_jit.sh: the command ended within ${delay} s (see $out/command.log)" >&2; exit 1; }
perf record -q -p "$pid" -o "$out/perf.data" -- sleep "$seconds" 2> /dev/null
perf script -i "$out/perf.data" -F ip 2> /dev/null | sort | uniq -c | sort -rn > "$out/ips.txt"
# The hottest 4 KiB pages outside the executable and the shared libraries perf could name: the JIT code.
awk '{p = substr($2, 1, length($2) - 3); c[p] += $1} END {for (k in c) print c[k], k}' "$out/ips.txt" |
  sort -rn | head -n "$pages" > "$out/pages.txt"
: > "$out/disassembly.txt"
while read -r _ page; do
  gdb -p "$pid" -batch -ex "x/1800i 0x${page}000 - 0x40" 2> /dev/null | grep '^ *0x' >> "$out/disassembly.txt" || true
done < "$out/pages.txt"
kill "$pid" 2> /dev/null || true
wait "$pid" 2> /dev/null || true

python3 - "$out" << 'EOF'
import re, sys, collections
out = sys.argv[1]
counts = {int(ip, 16): int(c) for c, ip in (line.split() for line in open(f"{out}/ips.txt"))}
code = {}
for line in open(f"{out}/disassembly.txt"):
    m = re.match(r"\s*0x([0-9a-f]+)[^:]*:\s*(.*)", line)
    if m:
        code[int(m.group(1), 16)] = m.group(2)
total = sum(counts.values())
covered = sum(counts.get(a, 0) for a in code)
by_mnemonic = collections.Counter()
with open(f"{out}/annotated.txt", "w") as f:
    for a in sorted(code):
        f.write(f"{counts.get(a, 0):7d} {a:x} {code[a]}\n")
        by_mnemonic[code[a].split()[0] if code[a] else "?"] += counts.get(a, 0)
with open(f"{out}/summary.txt", "w") as f:
    f.write(f"samples {total}, on the disassembled pages {covered} ({100 * covered / max(total, 1):.0f} %)\n")
    for m, c in by_mnemonic.most_common(30):
        f.write(f"{c:7d} {100 * c / max(covered, 1):5.1f} %  {m}\n")
print(open(f"{out}/summary.txt").read(), end="")
EOF
