// Window presentation: the projector image as computed on the CPU (the
// 8-bit values written to the PNG: compensated, Rec.709 transfer applied),
// copied unchanged to the window (nearest texel at 1:1, bilinear when the
// window is another size).

uniform sampler2D u_src;
in vec2 v_uv;
layout(location = 0) out vec4 o_color;

void main() { o_color = vec4(texture(u_src, v_uv).rgb, 1.0); }
