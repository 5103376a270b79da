// Shared by the storage-buffer linear kernels (linear_tiled.comp: fp32 FMA; linear_coopmat.comp: tensor
// cores): bindings, push constants, guarded element loads and the epilogue, so the two families differ only
// in how the tile product is formed. Same push block and epilogue meaning as the texel kernel
// (linear.comp); the host (ops_linear.cpp) binds every buffer from an aligned-down offset and passes
// the element offsets.

#include "linear_epilogue.glsl"
#include "gemm_operands.glsl"
