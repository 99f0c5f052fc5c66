// test_gradient_frag.glsl: smoke test, writes the interpolated _uv_ (red = x, green = y)
// so each pixel centre reads back ((i + 0.5) / width, (j + 0.5) / height, 0.25, 1).
void main()
{
  frag_color = vec4(uv, 0.25, 1.0);
}
