// Constant-colour pass over the same mesh and vertex format as the shading
// pass: the benchmark's reference for what rasterization alone costs.
layout(location = 0) out vec4 o_display;
void main() { o_display = vec4(0.5, 0.5, 0.5, 1.0); }
