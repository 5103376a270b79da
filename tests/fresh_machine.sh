#!/usr/bin/env bash
# A whole-machine rehearsal of the README's two commands (opt-in, not in CI; root; minutes to an hour):
#   sudo tests/fresh_machine.sh              demo command, then the test command through its default pass
#   sudo tests/fresh_machine.sh --all        the test command through every pass (as CI; about an hour on 2 cores)
#   sudo tests/fresh_machine.sh --keep       leave the root in place afterwards (its path is printed)
# It makes a clean Debian 12 root with debootstrap from the Debian archive this machine's apt already uses, copies
# in a clean clone of this repository's HEAD (committed files only), and runs the README's two commands there,
# verbatim as README.md writes them (read from README.md, not retyped here), timing each. Only what the machine
# needs to reach the archives comes along: its apt sources and settings, DNS, proxy variables, and its extra
# certificate authorities (/usr/local/share/ca-certificates/, NODE_EXTRA_CA_CERTS for npm), so a registry reached
# through a TLS-inspecting proxy works as on the host. The times go in docs/testing.md ("Fresh machine").
set -Eeuo pipefail
trap 'rc=$?; echo "tests/fresh_machine.sh: line $LINENO failed (exit $rc): $BASH_COMMAND" >&2' ERR
cd "$(dirname "$0")/.."
repo="$(pwd)"
commit="$(git rev-parse HEAD)"  # fixed now: the repository may move on while the rehearsal runs
passes="default"
keep=0
for arg in "$@"; do
  case "$arg" in
    --all) passes="" ;;
    --keep) keep=1 ;;
    -h|--help) sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "tests/fresh_machine.sh: unknown argument '$arg' (--all, --keep, --help)" >&2; exit 2 ;;
  esac
done
[ "$(id -u)" -eq 0 ] || { echo "tests/fresh_machine.sh: needs root (debootstrap, chroot, mounts)" >&2; exit 2; }
if ! command -v debootstrap >/dev/null; then
  echo "Installing debootstrap (this script's only tool)"
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends debootstrap
fi

# The README's two commands, as written there: the first and second ```sh blocks of "## Two commands".
readme_command() {
  awk -v want="$1" '/^## Two commands/ {on=1} on && /^```sh$/ {n++; grab=(n==want); next}
                    on && /^```$/ {grab=0} grab {print}' README.md
}
demo_cmd="$(readme_command 1)"
test_cmd="$(readme_command 2)"
[ -n "$demo_cmd" ] && [ -n "$test_cmd" ] || { echo "tests/fresh_machine.sh: README.md's two commands not found" >&2; exit 1; }

archive="$( { grep -hE '^URIs:' /etc/apt/sources.list.d/*.sources 2>/dev/null || true
              grep -hE '^deb ' /etc/apt/sources.list 2>/dev/null || true
            } | awk '{print $2}' | { grep -v -- '-security' || true; } | head -n1)"
[ -n "$archive" ] || { echo "tests/fresh_machine.sh: no Debian archive in /etc/apt/sources.list{,.d}" >&2; exit 1; }

work="$(mktemp -d /var/tmp/dvs-fresh.XXXXXX)"
R="$work/root"
mounted=()
cleanup() {
  local m
  for ((i=${#mounted[@]}-1; i>=0; i--)); do umount -l "${mounted[$i]}" 2>/dev/null || true; done
  if [ "$keep" = 1 ]; then echo "tests/fresh_machine.sh: the root stays in $R"; else rm -rf "$work"; fi
}
trap cleanup EXIT

t0=$(date +%s)
echo "== debootstrap bookworm from $archive into $R"
debootstrap --variant=minbase bookworm "$R" "$archive" > "$work/debootstrap.log" 2>&1 ||
  { tail -n 30 "$work/debootstrap.log" >&2; echo "tests/fresh_machine.sh: debootstrap failed ($work/debootstrap.log)" >&2; exit 1; }
t_boot=$(( $(date +%s) - t0 ))

# How this machine reaches the archives: its apt sources and settings, DNS, certificate authorities.
rm -f "$R/etc/apt/sources.list"
cp -a /etc/apt/sources.list.d/*.sources "$R/etc/apt/sources.list.d/" 2>/dev/null || true
[ -f /etc/apt/sources.list ] && cp /etc/apt/sources.list "$R/etc/apt/sources.list"
# only the enabled sources: a disabled vendor list stays out, as on a new machine
find "$R/etc/apt/sources.list.d" -name '*disabled*' -delete
cp -a /etc/apt/apt.conf.d/. "$R/etc/apt/apt.conf.d/"
cp -L /etc/resolv.conf "$R/etc/resolv.conf"
if compgen -G "/usr/local/share/ca-certificates/*" >/dev/null; then
  mkdir -p "$R/usr/local/share/ca-certificates"
  cp -a /usr/local/share/ca-certificates/. "$R/usr/local/share/ca-certificates/"
fi
# git and the CA store: what a person has on a machine they cloned dvs onto (the clone itself is copied in below).
chroot "$R" /bin/sh -c 'apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends ca-certificates git sudo >/dev/null && update-ca-certificates >/dev/null'

for m in proc sys dev dev/pts; do
  mkdir -p "$R/$m"
  case "$m" in
    proc) mount -t proc proc "$R/proc" ;;
    sys) mount -t sysfs sys "$R/sys" ;;
    *) mount --bind "/$m" "$R/$m" ;;
  esac
  mounted+=("$R/$m")
done
mkdir -p "$R/dev/shm" "$R/run"; mount -t tmpfs tmpfs "$R/run"; mounted+=("$R/run")

echo "== a clean clone of ${commit:0:7} into /root/dvs"
git clone -q --no-local "$repo" "$R/root/dvs"
git -C "$R/root/dvs" checkout -q "$commit"

# The environment a person's shell would have here: proxies and the CA bundle node should trust.
envs=(HOME=/root PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin LANG=C.UTF-8 TERM=dumb
      NODE_EXTRA_CA_CERTS=/etc/ssl/certs/ca-certificates.crt LP_NUM_THREADS="${LP_NUM_THREADS:-2}")
for v in http_proxy https_proxy no_proxy HTTP_PROXY HTTPS_PROXY NO_PROXY; do
  [ -n "${!v:-}" ] && envs+=("$v=${!v}")
done
[ -n "$passes" ] && envs+=("DVS_PASSES=$passes")

run_timed() {  # name, command: runs in the root's clone, prints and returns its seconds through $secs
  local name="$1" cmd="$2" start rc
  echo "== $name (in the fresh root): $cmd"
  start=$(date +%s)
  set +e
  chroot "$R" /usr/bin/env -i "${envs[@]}" /bin/bash -c "cd /root/dvs && $cmd" 2>&1 | tee "$work/$name.log" |
    grep -E '^(-- \.ci/deps|== |Installing|100%|[0-9]+% tests passed|The following tests FAILED|.*Failed|Error|error)' || true
  rc=${PIPESTATUS[0]}
  set -e
  secs=$(( $(date +%s) - start ))
  echo "== $name: exit $rc after $((secs / 60)) min $((secs % 60)) s (log $work/$name.log)"
  return $rc
}
status=0
run_timed demo "$demo_cmd" && t_demo=$secs || { status=1; t_demo=$secs; }
if [ $status -eq 0 ]; then
  run_timed tests "$test_cmd" && t_test=$secs || { status=1; t_test=$secs; }
fi
echo
echo "== tests/fresh_machine.sh: ${commit:0:7}, $(nproc) cores, load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
printf '  debootstrap          %4d min %02d s\n' $((t_boot / 60)) $((t_boot % 60))
printf '  demo command         %4d min %02d s (bash .ci/deps, build, dvs demo)\n' $((t_demo / 60)) $((t_demo % 60))
[ -n "${t_test:-}" ] && printf '  test command         %4d min %02d s (%s)\n' $((t_test / 60)) $((t_test % 60)) \
  "${passes:+passes: $passes; }the build already done by the demo command is reused"
[ $status -eq 0 ] && echo "  both commands passed" || echo "  FAILED: see the logs above (--keep keeps them)"
if [ "$keep" != 1 ] && [ $status -ne 0 ]; then keep=1; echo "  (the root is kept because of the failure)"; fi
exit $status
