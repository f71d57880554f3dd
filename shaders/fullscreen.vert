// One triangle covering the viewport at the far plane (depth exactly 1, so
// with GL_EQUAL / GL_LEQUAL it fills only pixels no geometry covered), and
// the scene-frame points on the near and far planes behind each vertex: the
// map from clip to homogeneous scene coordinates is linear, so interpolating
// them without perspective gives every pixel's exact view ray.

uniform mat4 u_inv_mvp;  // clip -> scene frame (homogeneous)
noperspective out vec4 v_near;
noperspective out vec4 v_far;

void main() {
  vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);
  gl_Position = vec4(p, 1.0, 1.0);
  v_near = u_inv_mvp * vec4(p, -1.0, 1.0);
  v_far = u_inv_mvp * vec4(p, 1.0, 1.0);
}
