set(DVS_SHADER_VARIANTS
  "nn/scale_vec4  nn/scale.comp  VEC"
)
