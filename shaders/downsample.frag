// 2x supersampling resolve: each output pixel is the mean of its 2x2 block
// (box filter; for the tone-mapped target that is the display-space average
// a 2x FSAA resolve gives, as in the paper's 2880x2880 frame buffer).

uniform sampler2D u_src;
layout(location = 0) out vec4 o_color;

void main() {
  ivec2 p = 2 * ivec2(gl_FragCoord.xy);
  o_color = 0.25 * (texelFetch(u_src, p, 0) + texelFetch(u_src, p + ivec2(1, 0), 0) +
                    texelFetch(u_src, p + ivec2(0, 1), 0) + texelFetch(u_src, p + ivec2(1, 1), 0));
}
