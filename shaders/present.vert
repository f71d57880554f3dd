// Window presentation: a quad over u_rect (NDC x0, y0, x1, y1) drawn as a
// 4-vertex triangle strip, texture row 0 at the rectangle's top (images
// are stored top row first).

uniform vec4 u_rect;
uniform int u_gl_rows;  // 1: the texture's row 0 is the image's bottom (drawn by GL: the
                        // projector images of render_post.c), 0: its top (uploaded images)
out vec2 v_uv;

void main() {
  vec2 c = vec2(float(gl_VertexID & 1), float(gl_VertexID >> 1));
  gl_Position = vec4(mix(u_rect.xy, u_rect.zw, c), 0.0, 1.0);
  v_uv = vec2(c.x, u_gl_rows != 0 ? c.y : 1.0 - c.y);
}
