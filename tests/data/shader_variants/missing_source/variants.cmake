set(DVS_SHADER_VARIANTS
  "nn/scale_vec4  nn/scaled.comp  VEC4"
)
