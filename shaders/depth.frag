// Depth-only passes (the frame's z pre-pass and the sun's shadow map): no
// colour is written.
void main() {}
