// Window presentation: a quad over u_rect (NDC x0, y0, x1, y1) drawn as a
// 4-vertex triangle strip, texture row 0 at the rectangle's top (images
// are stored top row first).

uniform vec4 u_rect;
out vec2 v_uv;

void main() {
  vec2 c = vec2(float(gl_VertexID & 1), float(gl_VertexID >> 1));
  gl_Position = vec4(mix(u_rect.xy, u_rect.zw, c), 0.0, 1.0);
  v_uv = vec2(c.x, 1.0 - c.y);
}
