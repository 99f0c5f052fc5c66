/* preview_params.glsl: the uniform buffer (std140) of the preview's passes, replacing push
 * constants that exceeded the 128 bytes every backend guarantees. Declared by
 * gpu_shaders.py as uniform_buf(0, "AirlightPreviewParams", "pv"); the shaders read the
 * members under their old names through defines (inv_persp = pv.u_inv_persp, ...).
 * Filled by gpu_shaders.preview_params_ubo. */
struct AirlightPreviewParams {
  mat4 u_inv_persp;  /* inverse of projection * view */
  mat4 u_persp;      /* projection * view (the splat pass) */
  vec4 u_eye;        /* xyz view origin, w = 1 perspective / 0 orthographic */
  vec4 u_clip;       /* xyz unit view axis, w = clip_start */
  vec4 u_viewport;   /* xy target corner, zw full-resolution size */
  vec4 u_phase;      /* (kind, g, K, k) for biri06_airlight.glsl */
  vec4 u_fparams;    /* x = sigma_t, y = the World's transmittance (PREVIEW_ENV), z = noise
                        amplitude of the Gaussian fog (0: off) */
  ivec4 u_iparams;   /* x = light_count, y = scale, z = mode */
  vec4 u_noise;      /* Gaussian fog noise: xyz = offset (cells), w = 1 / scale (1/m) */
};
