// test_texel_frag.glsl: smoke test of float texture upload and read-back: each pixel
// reads its own texel of _values_ (RGBA32F) exactly (texelFetch, no filtering) and
// writes 2 * value + 1, which is exact in float32 for the test's inputs.
void main()
{
  frag_color = 2.0 * texelFetch(values, ivec2(gl_FragCoord.xy), 0) + 1.0;
}
