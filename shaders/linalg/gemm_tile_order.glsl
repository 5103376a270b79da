// The output tile (tile row, tile column) a GEMM workgroup computes, for a dispatch of (tile columns, tile rows,
// batch): in bands of `group_m` tile rows, each walked down its rows for one tile column after another, so that a
// column panel of W is read by group_m workgroups in a row and the band's X rows stay in L2 meanwhile (1: row by
// row, the grid's own order). Shared by linear_coopmat.comp and linear_coopmat2.comp.
uvec2 gemm_tile_order(uint group_m) {
  if (group_m <= 1u) return uvec2(gl_WorkGroupID.y, gl_WorkGroupID.x);
  const uint nx = gl_NumWorkGroups.x, ny = gl_NumWorkGroups.y;
  const uint pid = gl_WorkGroupID.y * nx + gl_WorkGroupID.x;
  const uint band = pid / (group_m * nx), first = band * group_m;
  const uint rows = min(ny - first, group_m), inband = pid - first * nx;
  return uvec2(first + inband % rows, inband / rows);
}
