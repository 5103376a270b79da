#!/usr/bin/env bash
# Checks what a dvs shared library exports: every defined dynamic symbol must be part of the public API, i.e. a
# name in namespace dvs that is not in one of its inner namespaces (dvs::vk::, dvs::geometry::, ...: engine
# internals), its typeinfo or vtable, or a dvs_* C function (dvs/dvs.h). Anything else (nlohmann::, cv::, std::
# template instantiations, internal dvs classes) fails the check, with the names listed.
# Usage: check_exports.sh LIBRARY [EXPECTED_SYMBOL...]   (each EXPECTED_SYMBOL must be exported, demangled, exact)
set -euo pipefail
lib="${1:?usage: check_exports.sh LIBRARY [EXPECTED_SYMBOL...]}"
shift
[ -f "$lib" ] || { echo "check_exports.sh: $lib: no such library" >&2; exit 2; }

symbols="$(nm -D --defined-only -C "$lib" | sed -E 's/^[0-9a-f]+ [A-Za-z] //' | sort -u)"
# The one inner name that is exported on purpose: the video component registers its OpenCV reader with the core
# library through it (engine/src/io/video_backend.hpp).
allowed_inner='^dvs::detail::'
public='^((typeinfo for|typeinfo name for|vtable for) )?dvs::([A-Z~]|[a-z_0-9]+[^a-z_0-9:]|[a-z_0-9]+$)|^dvs_[A-Za-z0-9_]+$'
leaks="$(printf '%s\n' "$symbols" | grep -Ev "$public" | grep -Ev "$allowed_inner" || true)"
count="$(printf '%s\n' "$symbols" | grep -c . || true)"
status=0
if [ -n "$leaks" ]; then
  echo "$lib exports $(printf '%s\n' "$leaks" | grep -c .) symbol(s) outside the public API (add DVS_API only to" \
       "public declarations; cmake/dvs_exports.map drops the rest):" >&2
  printf '  %s\n' "$leaks" | head -n 40 >&2
  status=1
fi
for want in "$@"; do
  if ! grep -Fxq -- "$want" <<<"$symbols"; then
    echo "$lib does not export '$want' (a public declaration without DVS_API, or the definition does not see it)" >&2
    status=1
  fi
done
[ $status -eq 0 ] && echo "$lib: $count exported symbols, all public API"
exit $status
