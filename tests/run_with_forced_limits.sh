#!/usr/bin/env bash
# Runs a command (e.g. ctest) with the device limits forced down (DVS_LIMITS), so that at the test models'
# tiny sizes every op takes the split paths the real size takes on lavapipe (one binding 128 MiB, one texel
# view 2^27 texels, one allocation 2 GiB):
#   tests/run_with_forced_limits.sh ctest --test-dir build --output-on-failure -j2
# binding=64KiB and texels=16384 split the transformer's and the VAE's activations over many bindings / texel
# views, alloc=4MiB cuts arenas into several blocks (the packs' largest single tensor, a VAE activation of
# 2.8 MiB, still fits one allocation), groups=64 splits grids. tests/golden_forced_limits.cpp lists which
# limit splits which op and checks that each op really split.
set -euo pipefail
export DVS_LIMITS="${DVS_FORCED_LIMITS:-binding=64KiB,texels=16384,alloc=4MiB,groups=64}"
echo "run_with_forced_limits.sh: DVS_LIMITS=$DVS_LIMITS"
exec "$@"
