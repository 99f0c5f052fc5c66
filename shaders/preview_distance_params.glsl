/* preview_distance_params.glsl: the uniform buffer (std140) of the distance pass
 * (preview_distance_*.glsl): eye and axis; model and persp stay push constants (128 bytes).
 * Declared as uniform_buf(0, "AirlightDistanceParams", "dv"). */
struct AirlightDistanceParams {
  vec4 u_eye;   /* xyz view origin, w = 1 perspective / 0 orthographic */
  vec4 u_axis;  /* orthographic: distance = dot(p, axis.xyz) + axis.w */
};
