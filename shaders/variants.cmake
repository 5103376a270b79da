# Shader variants: shaders compiled from another shader's source with preprocessor defines, so one source
# holds every variant of a kernel and no file exists only to #define a variant and #include another.
# Every shaders/**/*.comp is a shader of its own (named by its path without the extension, e.g.
# "nn/eltwise_binary"); each row below adds one more, compiled from a .comp with -D<NAME> for each define.
# Row: "<run-time name> <source .comp, below shaders/> <DEFINE>..."; a define is a bare name (#ifdef tests).
# The build (cmake/shaders.cmake) reads this table; ctest's shader_variants check holds it to that rule.
set(DVS_SHADER_VARIANTS
  # run-time name                 source                    defines
  "linalg/linear_nosubgroup       linalg/linear.comp        LINEAR_NO_SUBGROUPS"
  "nn/avgpool_time_vec4           nn/avgpool_time.comp      VEC4"
  "nn/cast_x8                     nn/cast.comp              X8"
  "nn/concat_copy_vec4            nn/concat_copy.comp       VEC4"
  "nn/concat_copy_tex4            nn/concat_copy.comp       VEC4 TEXEL"
  "nn/conv_coopmat_twin           nn/conv_coopmat.comp      TWIN"
  "nn/conv_gemm_nosubgroup        nn/conv_gemm.comp         CONV_NO_SUBGROUPS"
  "nn/conv_shifted_coopmat        linalg/linear_coopmat.comp CONV_SHIFTED"
  "nn/eltwise_affine_vec4         nn/eltwise_affine.comp    VEC4"
  "nn/eltwise_affine_tex4         nn/eltwise_affine.comp    TEXEL"
  "nn/eltwise_binary_vec4         nn/eltwise_binary.comp    VEC4"
  "nn/eltwise_binary_vec4_bcast   nn/eltwise_binary.comp    VEC4 Y_SCALAR"
  "nn/eltwise_binary_tex4         nn/eltwise_binary.comp    TEXEL"
  "nn/eltwise_unary_vec4          nn/eltwise_unary.comp     VEC4"
  "nn/eltwise_unary_tex4          nn/eltwise_unary.comp     TEXEL"
  "nn/gather_rows_vec4            nn/gather_rows.comp       VEC4"
  "nn/nonfinite_tex4              nn/nonfinite.comp         TEXEL"
  "nn/patchify_p2                 nn/patchify.comp          P2"
  "nn/patchify_inverse            nn/patchify.comp          INVERSE"
  "nn/patchify_inverse_p2         nn/patchify.comp          INVERSE P2"
  "nn/permute_vec4                nn/permute.comp           VEC4"
  "nn/permute_tex4                nn/permute.comp           VEC4 TEXEL"
  "test/access_probe_utexel       test/access_probe.comp    UNIFORM_TEXEL"
  "test/access_probe_stexel       test/access_probe.comp    STORAGE_TEXEL"
)
