// preview_distance_frag.glsl: writes the linear surface distance _Dvp_ the fog needs,
// as fog_preview_frag.glsl measures it: from the eye for a perspective view
// (eye.w = 1), from the near plane along the view axis for an orthographic one
// (Dvp = dot(wpos, axis.xyz) + axis.w). Nearest surface wins by the depth test.
void main()
{
  float Dvp = (eye.w > 0.5) ? length(wpos - eye.xyz) : dot(wpos, axis.xyz) + axis.w;
  frag_color = vec4(max(Dvp, 0.0), 0.0, 0.0, 1.0);
}
