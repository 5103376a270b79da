// Include AFTER the layout(local_size_x = ...) in; line: before it gl_WorkGroupSize is still (1,1,1).
// Flat invocation index for grids that ops::grid_1d() split over x and y (x ≤ 65535 groups).
uint flat_index() {
  return (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
}
