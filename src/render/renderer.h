/* The wall-eye renderer: headless OpenGL (EGL, desktop GL 3.3 core) drawing
 * a baked PRT scene through one wall's off-axis projection, with the
 * three-pass frame of Dmitriev et al. 2004, section 4.2:
 *   (a) a low-resolution luminance pass whose pixels feed the adaptation
 *       statistics (cv_renderer_luminance),
 *   (b) a depth-only pass at full resolution, then
 *   (c) PRT shading with glDepthFunc(GL_EQUAL) and depth writes off, so only
 *       visible pixels pay for shading and tone mapping (cv_renderer_shade),
 * Drago tone mapping + Rec.709 transfer in the fragment shader from the same
 * cv_drago_consts as the CPU operator, optional 2x supersampling, and a
 * linear HDR output.
 *
 * Relighting (exit radiance = lighting SH . transfer, as cv_prt_relight) runs
 * on the GPU once per cv_renderer_set_lighting, by transform feedback into a
 * vertex buffer that every later pass of every view reads (per vertex, like
 * the CPU, so the image is the CPU's vertex radiance interpolated); the
 * transfer vectors live in a GL buffer object read as a texture buffer (25
 * coefficients x 4 channels do not fit in the 16 vertex attributes GL
 * guarantees).  A sun (cv_lighting.has_sun) adds its direct light per pixel
 * with a shadow map of square texels, the beam's longer side over 2048 (bilinear PCF, in the
 * shader); its indirect light
 * goes through the interreflected transfer as in relight.c.  Windows (CV_MAT_WINDOW) are
 * not drawn: the background (a lat-long HDR image,
 * cv_renderer_set_background) shows wherever no opaque triangle covers a
 * pixel.  Negative and non-finite vertex radiance is set to 0 and counted
 * (cv_render_light_stats); pixels are not counted on the GPU.
 *
 * Speed: triangles are sorted along a Morton curve and drawn in chunks of
 * 1024 whose bounds are culled against each view's frustum; vertices are
 * renumbered in order of first use (compact index ranges per draw);
 * optionally back faces are culled (closed meshes only).  Per pixel the
 * shaders avoid what llvmpipe (no GPU; it runs every instruction of a
 * shader on every pixel, both sides of every branch) pays for: with a sun,
 * the triangles facing away from it are drawn with the variant without the
 * sun's code (opts.sun_split); Drago comes from a table and the transfer
 * from a polynomial instead of log/pow (opts.tone_exact, shaders/common.glsl;
 * the same numbers within ~3e-7); the LCD panel is a variant of its own.
 * Timings per pass (glFinish-bracketed) come back in cv_frame_timing.

 * Coordinates: the projection (cv_offaxis) is in CAVE coordinates; the scene
 * is drawn at scene point = CAVE point + scene_offset (no rotation).
 *
 * EGL: EGL_PLATFORM_SURFACELESS_MESA (Mesa, llvmpipe without a GPU), falling
 * back to EGL_EXT_platform_device (NVIDIA and other vendor drivers), then
 * the default display.  GL entry points come from glvnd's libOpenGL with
 * GL_GLEXT_PROTOTYPES (it exports every core function up to 4.6).
 * A renderer owns its context and makes it current on each call: use one
 * renderer per thread. */
#ifndef CV_RENDER_RENDERER_H
#define CV_RENDER_RENDERER_H

#include <stddef.h>
#include <stdint.h>

#include "core/image.h"
#include "core/status.h"
#include "prt/prt.h"
#include "prt/relight.h"
#include "prt/scene_light.h"
#include "tonemap/drago.h"
#include "view/offaxis.h"

struct cv_window_spec;

typedef struct cv_render_opts {
  int half_transfer; /* 1: transfer stored as half floats (RGBA16F, or in memory for the CPU
                        relight), half the bytes (relative pixel difference to float: median
                        1.5e-4, p99 1.4e-3; docs/benchmarks.md); 0: floats; -1 (default): half
                        when the relight runs on the CPU (opts.relight_cpu: the relight reads
                        every transfer byte per lighting change, 61 MB instead of 122 MB for
                        the 571K cabin, 40-48% less time), floats on a GPU */
  int shadow_res;    /* sun shadow map size in texels (default 2048) */
  int timing;        /* 1: bracket passes with glFinish and fill cv_frame_timing with wall-clock
                        ms (default); 2: the same with the process's CPU ms (all threads: the
                        work done, for comparisons on a loaded machine); 0: off */
  int display_float; /* 1: tone-mapped target RGBA32F (exact values); 0: RGBA8, what a
                        display gets, quantised to k/255 (default) */
  int cull_frustum;  /* 1: skip chunks of 1024 triangles outside the view (default 1) */
  int cull_back;     /* 1: cull back faces (only for closed, consistently wound meshes
                        such as the cabin; the CPU reference sees both sides) (default 0);
                        -1: when cv_renderer_mesh_closed (what `cave run` asks for) */
  int debug_clear;   /* 1: clear colour targets to -1 before shading (tests find holes) */
  int depth_less;    /* 1: no z pre-pass, shade with GL_LESS (reference for tests; also the
                        cheaper frame for small views on llvmpipe, where the pre-pass costs a
                        whole geometry pass: `cave run` uses it up to 720^2 pixels) */
  int sun_split;     /* 1: with a sun, draw the triangles facing away from it (n_t . s <= 0:
                        no direct sun) with the shader without the sun's per-pixel code
                        (default 1; the image is the same) */
  int gpu;           /* CV_GPU_AUTO (default), CV_GPU_SOFTWARE or a hardware EGL device index
                        (view/cave.h; render/egl_context.h says how each is chosen) */
  const struct cv_window_spec *window; /* non-NULL: draw on this X11 window (connected and
                        created here; cv_renderer_present / _swap); NULL: headless (default) */
  int tone_exact;    /* 1: Drago and the transfer computed in the shader with log and pow
                        (log, log, pow + 3 pow per pixel) instead of a table for Drago and a
                        polynomial for the transfer (default 0; the table falls back to it
                        by itself when it misses its tolerance) */
  int shadow_cull;   /* 1: the sun's shadow map holds only the triangles facing away from the
                        sun (n_t . s <= 0, plus those within split_margin of grazing): half the
                        triangles, and no receiver in the map (no acne).  Exact when every
                        surface seen from the air is seen from its front (closed, consistently
                        wound meshes with normals towards the air, as cull_back asks): the
                        first opaque hit from a visible point towards the sun then faces away
                        from it.  0: every triangle; -1 (default): 1 when the mesh (opaque and
                        window triangles) is closed and consistently wound, i.e. every
                        directed edge appears once and its reverse once
                        (cv_renderer_mesh_closed) */
  double shadow_reuse; /* texels: a lighting change whose sun moved less than this (at the
                        map's extent) keeps the shadow map and its matrices (default 0.5;
                        0: redraw on every change with a sun) */
  double split_margin; /* |s - s0| up to which the sun split of direction s0 is reused: the
                        triangles within this of grazing are drawn with the sun's code and
                        into a culled shadow map, so reuse stays exact (default 0.05) */
  double shadow_casters; /* metres: the shadow map draws a simplified copy of the opaque
                        triangles (render_casters.c: meshoptimizer's edge collapses on the
                        welded positions, window borders kept) whose surface stays within
                        this of the mesh's, instead of the mesh (default 0.001, under the
                        2048^2 map's ~1.5 mm texel on the cabin; 0: the mesh itself) */
  int relight_cpu;    /* 1: relight on the CPU (render_relight.c: the same float sums as
                        relight.vert, OpenMP threads, then one buffer upload) instead of by
                        transform feedback; 0: transform feedback; -1 (default): the CPU
                        when the GL is software (llvmpipe runs vertex shaders on one thread
                        and fetches texel by texel: 2.5-4x the CPU loop), feedback on a GPU */
  int lum_stats_gpu;  /* cv_renderer_shade_stats: 1: reduce the HDR target in a shader
                        (lum_reduce.frag) and read back only the luminance image; 0: read the
                        HDR image back and reduce it with cv_lum_downsample on the CPU; -1
                        (default): the shader on a hardware device (on an H200 it saves the
                        1440^2 HDR read-back, 6.4 ms a frame), the CPU with a software GL
                        (llvmpipe fetches texel by texel: 6.0 ms for 360^2 -> 128^2 against
                        1.1 ms on the CPU) */
} cv_render_opts;

/* --transfer auto|float|half (`cave render`, `cave run`) into opts.half_transfer
 * (-1, 0, 1); returns 0, or -1 for anything else. */
int cv_render_transfer_parse(const char *s, int *half_transfer);

/* Defaults: half-float transfer with the CPU relight (float on a GPU), 2048 shadow map, timing on, 8-bit display
 * target, frustum culling on, back-face culling off, no debug, sun split on,
 * tone-mapping table and transfer polynomial. */
void cv_render_default_opts(cv_render_opts *o);

/* One wall-eye view. */
typedef struct cv_render_view {
  cv_offaxis proj;        /* the wall's off-axis projection for this eye (CAVE frame) */
  double scene_offset[3]; /* scene point = CAVE point + scene_offset */
  int w, h;               /* output pixels */
  int supersample;        /* 1, or 2: shade at 2w x 2h and box-filter down */
} cv_render_view;

/* Milliseconds per pass, wall clock between glFinish calls (opts.timing).
 * Each call sets the fields of the passes it ran and leaves the others. */
typedef struct cv_frame_timing {
  double relight_ms;    /* set_lighting: transform-feedback relight (+ clamp count) */
  double shadow_ms;     /* set_lighting: sun shadow map (0 when reused) */
  double lum_ms;        /* luminance pass, draw only */
  double lum_read_ms;   /* luminance read-back */
  double depth_ms;      /* depth-only pass (incl. depth clear) */
  double shade_ms;      /* PRT shading pass, geometry only */
  double background_ms; /* background (environment) fill */
  double resolve_ms;    /* supersampling 2x2 box filter */
  double read_ms;       /* read-back of the shaded image(s) */
  double unlit_ms;      /* unlit reference pass (cv_renderer_unlit) */
  double split_ms;      /* set_lighting: the sun split (CPU partition + upload; 0 when reused) */
  int shadow_reused;    /* set_lighting: 1 when the shadow map was kept (opts.shadow_reuse) */
} cv_frame_timing;

/* Albedo textures of a textured PRT (CV_PRT_TEXTURED; render_texture.c):
 * a pixel on a textured triangle is texture(uv) x the relit radiance, as in
 * `cave shade --view`.  A texture that cannot be read is not an error: its
 * material shows its stored albedo (the texture's mean) and is counted. */
typedef struct cv_render_tex_info {
  int layers;            /* textured materials (layers of the texture array); 0: none */
  int w, h;              /* the layers' size in texels (the largest texture's, halved
                            until the array fits 1 GiB and the GL's limits) */
  int unread;            /* textures that could not be read (shown as their mean) */
  size_t split_vertices; /* vertices added where triangle corners' UVs differ */
  char first_error[320]; /* the first unread texture's message, "" if none */
} cv_render_tex_info;

/* Relighting counts of the last cv_renderer_set_lighting. */
typedef struct cv_render_light_stats {
  uint64_t clamped; /* vertex channels negative (SH ringing) or non-finite, set to 0 */
} cv_render_light_stats;

typedef struct cv_renderer cv_renderer;

/* Albedo textures: fills info (cv_render_tex_info above); returns info->layers. */
int cv_renderer_textures(const cv_renderer *r, cv_render_tex_info *info);

/* Starts EGL + GL, uploads the PRT's opaque triangles, positions and
 * transfer (copied: prt may be freed afterwards), builds the programs.
 * opts may be NULL (defaults).  *out owned by the caller (cv_renderer_destroy).
 * Errors: CV_ERR_BACKEND with the EGL/GL failure ("no EGL display: ...",
 * "cannot create a GL 3.3 core context", a shader log), CV_ERR_RANGE (mesh
 * larger than the GL limits), CV_ERR_INVALID, CV_ERR_NOMEM. */
int cv_renderer_create(const cv_prt *prt, const cv_render_opts *opts, cv_renderer **out,
                       cv_err *err);
/* Frees the GL objects and the context; accepts NULL. */
void cv_renderer_destroy(cv_renderer *r);

/* 1 when the context renders in software (llvmpipe), 0 on a hardware GPU. */
int cv_renderer_is_software(const cv_renderer *r);
/* Hardware EGL devices this process sees (whatever was chosen). */
int cv_renderer_hw_devices(const cv_renderer *r);
/* "device 0 (hardware, ...)", "software device (EGL device 0)", "x11 :99". */
const char *cv_renderer_platform(const cv_renderer *r);

/* ---- window presentation (opts.window) ----------------------------------
 * Layouts of cv_renderer_present (view/cave.h cv_stereo_mode): passive
 * (left only, whole window), side-by-side (left | right), top-bottom (left
 * above right).  Quad-buffered stereo is refused at create time: EGL has no
 * stereo configs. */

/* Draws the 8-bit RGB image(s) (w x h, row 0 at the top; right NULL
 * unless a packed stereo layout) into the window's back buffer, then
 * glFinish: the frame is ready to swap.  Errors: CV_ERR_INVALID (no window,
 * sizes), CV_ERR_BACKEND. */
int cv_renderer_present(cv_renderer *r, const uint8_t *left, const uint8_t *right, int w, int h,
                        int layout, cv_err *err);
/* Swaps the window (eglSwapBuffers; vsync interval 1).  Errors: CV_ERR_BACKEND. */
int cv_renderer_swap(cv_renderer *r, cv_err *err);
/* Window events since the last poll: CV_WIN_OK, _CLOSED, _ESCAPE, _LOST
 * (render/window.h); CV_WIN_OK without a window. */
int cv_renderer_window_poll(cv_renderer *r);
/* The window's size (0 x 0 without one). */
void cv_renderer_window_size(const cv_renderer *r, int *w, int *h);

/* 1 when the scene's triangles (opaque and windows, degenerate ones left
 * out) are closed and consistently wound: each directed edge once, its
 * reverse once (checked at create; opts.shadow_cull -1 follows it). */
int cv_renderer_mesh_closed(const cv_renderer *r);
/* 1 when the relight runs on the CPU (opts.relight_cpu), 0 by transform feedback. */
int cv_renderer_relight_on_cpu(const cv_renderer *r);
/* 1 when the transfer is stored as half floats (opts.half_transfer). */
int cv_renderer_half_transfer(const cv_renderer *r);
/* 1 when cv_renderer_shade_stats reduces on the GPU (opts.lum_stats_gpu). */
int cv_renderer_lum_stats_on_gpu(const cv_renderer *r);

/* The sun's shadow casters (opts.shadow_casters), built with the first
 * shadow map: built 0 before that (or with shadow_casters 0). */
typedef struct cv_shadow_casters {
  double tolerance_m;    /* opts.shadow_casters */
  size_t mesh_triangles; /* opaque triangles of the mesh */
  int built;             /* 1 once built */
  size_t triangles;      /* caster triangles */
  double error_m;        /* the simplifier's largest error (m), <= tolerance_m */
  int culled;            /* 1: the map holds only the casters facing away from the sun
                            (shadow_cull, and closure defects within 2% of the triangles) */
  size_t defects;        /* directed edges used twice + border edges not the mesh's */
  size_t drawn;          /* triangles drawn into the last map */
  double build_ms;       /* wall ms of the build */
} cv_shadow_casters;
int cv_renderer_shadow_casters(const cv_renderer *r, cv_shadow_casters *out);

/* "renderer | version" of the GL context, e.g. "llvmpipe (LLVM 15...) | 4.5 (Core Profile) Mesa". */
const char *cv_renderer_gl_name(const cv_renderer *r);

/* Split window lights (`cave shade --split`, cv_scene_light_split): n
 * directional lights cut out of the SH lighting.  Their indirect light goes
 * through the interreflected transfer (sum_k E_k y_i(s_k) added to the
 * lighting that multiplies ti, as cv_prt_relight_ex) and their direct light,
 * with ray-traced visibility, comes per vertex in direct_rgb (3 * the PRT's
 * vertex count, PRT vertex order, as cv_split_direct gives it: a textured
 * receiver without its own albedo, which the renderer applies as for the
 * transfer), added in the relight before negative channels are clamped, as
 * cv_prt_relight_ex (a texture buffer of one RGBA32F texel per vertex).
 * Takes effect at the next cv_renderer_set_lighting; n = 0 removes them.
 * Errors: CV_ERR_INVALID (n < 0, NULL arrays), CV_ERR_NONFINITE, CV_ERR_NOMEM. */
int cv_renderer_set_split(cv_renderer *r, const cv_dir_light *lights, int n,
                          const float *direct_rgb, cv_err *err);

/* Sets the lighting: relights every vertex on the GPU (as cv_prt_relight
 * without its ray-traced sun) and, with a sun, renders its shadow map.
 * l->bands must be >= the PRT's bands.  stats (may be NULL: then the
 * relit buffer is not read back) gets the clamp count; t (may be NULL) relight_ms, split_ms, shadow_ms and shadow_reused.
 * Errors: CV_ERR_RANGE (bands), CV_ERR_NONFINITE (lighting), CV_ERR_BACKEND. */
int cv_renderer_set_lighting(cv_renderer *r, const cv_lighting *l, cv_render_light_stats *stats,
                             cv_frame_timing *t, cv_err *err);

/* ---- shared lighting (render_share.c) ------------------------------------
 * What cv_renderer_set_lighting produces (the relit vertex colours, the
 * sun's shadow map with its matrices, the sun split) copied into a byte
 * buffer by one renderer and taken from it by another of the same scene
 * (same PRT, opts.shadow_res and kind of GL: a software and a hardware GL
 * may relight to other bits), which then draws images bit-identical to those
 * it would draw after computing the lighting itself: the float bits are
 * copied, never converted.  `cave run --share-lighting` shares them among
 * the wall-eyes of one host (docs/service.md, "Shared lighting"). */

/* Bytes of an export buffer for r (the largest export: with a shadow map
 * of opts.shadow_res texels and a split). */
size_t cv_renderer_lighting_bytes(const cv_renderer *r);
/* Fingerprint of r's scene for sharing (mesh, vertex and chunk counts,
 * shadow size): renderers whose fingerprints differ cannot share. */
uint64_t cv_renderer_lighting_scene(cv_renderer *r);
/* Writes the current lighting's products into buf (cap >= _bytes).  A
 * buffer that holds an export of this renderer already gets the shadow map
 * and the split only when they were redrawn since (the relit colours
 * always), so keep exporting into one buffer.  Errors: CV_ERR_INVALID (no
 * lighting set), CV_ERR_RANGE (cap), CV_ERR_BACKEND. */
int cv_renderer_lighting_export(cv_renderer *r, void *buf, size_t cap, cv_err *err);
/* Takes an export instead of cv_renderer_set_lighting: uploads the relit
 * colours, and the shadow map and split unless it took those of the same
 * generation already.  t (may be NULL) gets the upload times in relight_ms,
 * split_ms and shadow_ms, shadow_reused = 1 when the map was kept.
 * Errors: CV_ERR_FORMAT (not an export, truncated), CV_ERR_INVALID (another
 * scene or shadow size), CV_ERR_BACKEND. */
int cv_renderer_lighting_import(cv_renderer *r, const void *buf, size_t len, cv_frame_timing *t,
                                cv_err *err);

/* Triangles a frame of view v draws (those of the chunks inside its
 * frustum; CPU only): what its passes cost, relatively.  `cave run` makes
 * the cheapest wall-eye of a host its lighting leader.  0 for a bad view. */
size_t cv_renderer_view_triangles(const cv_renderer *r, const cv_render_view *v);

/* Forgets the lighting, its shadow map and split: the next
 * cv_renderer_set_lighting computes everything (after an import that may
 * have read a buffer while it was rewritten). */
void cv_renderer_lighting_forget(cv_renderer *r);

/* Sets the background seen through the windows: a lat-long RGB image
 * (c >= 3, row 0 = zenith; docs/conventions.md), copied; NULL = black.
 * Errors: CV_ERR_INVALID, CV_ERR_BACKEND. */
int cv_renderer_set_background(cv_renderer *r, const cv_image *latlong, cv_err *err);

/* The dashboard LCD as the driver sees it (the LCD final gather's image,
 * issue 6): fragments within 3 mm of the panel rectangle (centre, axes u
 * along its width and v along its height, normalised here, sizes in metres;
 * scene frame) take their radiance from img (linear RGB, c >= 3, row 0 at
 * the top = the +v edge, bilinear) instead of the PRT, in every pass.  The
 * image is copied; NaN/Inf/negative texels become 0 and are counted
 * (cv_renderer_panel_invalid).  img NULL turns the panel off.
 * Errors: CV_ERR_INVALID, CV_ERR_RANGE (texture limit), CV_ERR_BACKEND. */
int cv_renderer_set_panel(cv_renderer *r, const float center[3], const float u[3],
                          const float v[3], const float size[2], const cv_image *img, cv_err *err);
/* Texels of the last panel image that were not finite and >= 0. */
uint64_t cv_renderer_panel_invalid(const cv_renderer *r);

/* The Drago table of the last tone-mapped cv_renderer_shade (see
 * shaders/common.glsl): *drago_err (may be NULL) gets its largest error
 * measured against the curve when it was built, relative with a floor of
 * 1e-4 on Ld (NaN before any).  Returns 1 when the shader used it, 0 when it
 * computed the curve (opts.tone_exact, or an error above 2e-6). */
int cv_renderer_tone_table(const cv_renderer *r, double *drago_err);

/* Samples sl's background radiance (cv_scene_light_background, sun
 * included) at the texel centres of a w x w/2 lat-long image; *out owned by
 * the caller.  Errors: CV_ERR_INVALID (w < 2), CV_ERR_NOMEM. */
int cv_render_background_image(const cv_scene_light *sl, int w, cv_image **out);

/* Pass (a): renders the view's luminance (Rec.709 Y, linear, same radiance
 * as the shading pass, background included) at out->w x out->h (out: c = 1,
 * any size, typically 128x128; row 0 at the top = the wall's pc edge) and
 * reads it back.  Errors: CV_ERR_INVALID (bad view or image), CV_ERR_BACKEND. */
int cv_renderer_luminance(cv_renderer *r, const cv_render_view *v, cv_image *out,
                          cv_frame_timing *t, cv_err *err);

/* Passes (b) and (c): depth pre-pass, then shading with depth EQUAL, then
 * the background, the supersampling resolve and the read-back of
 *   out_display (may be NULL): Drago display values per channel in [0, 1]
 *                 with the constants dc, plus the Rec.709 transfer when
 *                 `transfer` is non-zero (display-linear otherwise);
 *   out_hdr (may be NULL): linear radiance.
 * At least one output; each c = 3, v->w x v->h, row 0 at the top.  Both come
 * from the same pass (two render targets).  dc may be NULL without
 * out_display.  Errors: CV_ERR_INVALID, CV_ERR_BACKEND. */
int cv_renderer_shade(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc,
                      int transfer, cv_image *out_display, cv_image *out_hdr,
                      cv_frame_timing *t, cv_err *err);

/* cv_renderer_shade plus the luminance statistics of the frame's linear
 * radiance, reduced on the GPU from the HDR target (no HDR read-back: pass
 * out_hdr NULL unless the image itself is wanted) or on the CPU from the
 * read-back HDR image (opts.lum_stats_gpu, cv_renderer_lum_stats_on_gpu): out_lum (c = 1, any size
 * up to the GL limit, row 0 at the top) gets what cv_lum_downsample (tonemap/foveal.h)
 * gives of the HDR image: the area-weighted mean Rec.709 Y of the pixels
 * under each footprint, NaN/Inf/negative pixels left out and counted in
 * *n_invalid (a footprint of such pixels only: NaN), *max_y the largest
 * valid Y (0 when none).  The GPU sums in float (exact weights), the
 * final divisions are in double: within 1e-5 of cv_lum_downsample
 * (tests/render).  t->lum_ms: the reduction and its read-back (w x h x 16
 * bytes), or the CPU's reduction (the HDR read-back is then in read_ms).  out_display, out_hdr may be NULL; max_y, n_invalid may be NULL.
 * Errors: those of cv_renderer_shade, CV_ERR_INVALID (out_lum's shape). */
int cv_renderer_shade_stats(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc,
                            int transfer, cv_image *out_display, cv_image *out_hdr,
                            cv_image *out_lum, double *max_y, uint64_t *n_invalid,
                            cv_frame_timing *t, cv_err *err);

/* The three passes in order: luminance into out_lum (may be NULL: skipped),
 * then cv_renderer_shade.  For a single wall-eye; a CAVE computes dc from
 * the luminance of all wall-eyes between the two halves. */
int cv_renderer_frame(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc,
                      int transfer, cv_image *out_display, cv_image *out_hdr, cv_image *out_lum,
                      cv_frame_timing *t, cv_err *err);

/* ---- the frame on the GPU (render_post.c) ---------------------------------
 * What a wall-eye does per eye without a CPU image (issue 29): shade with
 * the display image left on the GPU (cv_renderer_shade_gpu), its patch
 * means reduced there (cv_renderer_patch_means: 24 bytes a patch come back),
 * equation 7 (Bimber et al. 2006: I = clamp(I0 - up(delta), 0, 1)), the
 * clamp and Drago's Rec.709 transfer in a shader into the eye's 8-bit
 * projector image (cv_renderer_post, "slot" 0 or 1), drawn into the window
 * by cv_renderer_present_slots.  Full images come back only when asked for
 * (cv_renderer_post_read, cv_renderer_display_read).  The patch sums are
 * doubles (GL_ARB_gpu_shader_fp64); a GL without it cannot run this path
 * (cv_renderer_post_available says why).  Needs opts.display_float. */

/* 1 when this GL runs the post pass; else 0 and why (may be NULL). */
int cv_renderer_post_available(cv_renderer *r, char *why, size_t cap);
/* The wall's patch grid: nu x nv cells with edges eu[0..nu], ev[0..nv]
 * (ascending 0..1, NULL = uniform; row v = 0 at the bottom, as
 * compensate/resample.h) over w x h images; makes the weight tables and
 * targets (once per grid).  Errors: CV_ERR_INVALID (sizes; more patches
 * than pixels), CV_ERR_BACKEND (no fp64: see cv_renderer_post_available),
 * CV_ERR_NOMEM. */
int cv_renderer_post_grid(cv_renderer *r, int nu, int nv, const double *eu, const double *ev, int w, int h,
                          cv_err *err);
/* Passes (b) and (c) as cv_renderer_shade_stats with the display image
 * (display-linear Drago values, no transfer) drawn into a float target and
 * left there, the luminance statistics always reduced on the GPU; out_hdr
 * (may be NULL) is read back. */
int cv_renderer_shade_gpu(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc,
                          cv_image *out_hdr, cv_image *out_lum, double *max_y, uint64_t *n_invalid,
                          cv_frame_timing *t, cv_err *err);
/* Patch means of the last display image (3 nu nv, index v nu + u): what
 * cv_downsample_to_patches gives of it on the CPU, within double rounding. */
int cv_renderer_patch_means(cv_renderer *r, double *out, cv_err *err);
/* Copies the last display image into slot's own texture, so that the next
 * eye can be shaded before this one's post pass (cv_renderer_post, kept). */
int cv_renderer_display_keep(cv_renderer *r, int slot, cv_err *err);
/* Equation 7 with delta (3 nu nv floats, down(I0) - I_P; NULL: none), the
 * clamp to [0, 1] and the Rec.709 transfer, of the last display image (or
 * of the one kept in slot, kept = 1), into slot's 8-bit image. */
int cv_renderer_post(cv_renderer *r, int slot, int kept, const float *delta, cv_err *err);
/* Slot's image black (an eye with no image this frame). */
int cv_renderer_post_black(cv_renderer *r, int slot, cv_err *err);
/* Slot's 8-bit codes into codes (3 w h, row 0 at the top). */
int cv_renderer_post_read(cv_renderer *r, int slot, uint8_t *codes, cv_err *err);
/* The last display image (float) into img (c = 3, its size). */
int cv_renderer_display_read(cv_renderer *r, cv_image *img, cv_err *err);
/* Draws the slots' images into the window's back buffer as
 * cv_renderer_present draws uploaded codes (slot 0, and 1 for a packed
 * stereo layout), then glFinish.  Errors: as cv_renderer_present. */
int cv_renderer_present_slots(cv_renderer *r, int layout, cv_err *err);

/* Bytes read back from the GL and uploaded to it since create (images,
 * statistics, patch means, relit vertices, tables, textures). */
void cv_renderer_io(const cv_renderer *r, uint64_t *read_bytes, uint64_t *uploaded_bytes);
/* GPU time of a frame's GL work with a timer query (GL_TIME_ELAPSED, core
 * since 3.3): begin before the frame's first pass, end after its last;
 * cv_renderer_gpu_timer_result waits for it (after the present's glFinish
 * it is ready) and returns the ms, or NaN when no query ran. */
void cv_renderer_gpu_timer_begin(cv_renderer *r);
void cv_renderer_gpu_timer_end(cv_renderer *r);
double cv_renderer_gpu_timer_result(cv_renderer *r);
/* Sets opts.timing after create (0: no glFinish between passes, as a GPU
 * frame wants; 1, 2: see cv_render_opts). */
void cv_renderer_set_timing(cv_renderer *r, int timing);

/* Benchmark reference: the depth pre-pass and then the same mesh with the
 * same vertex format in a constant colour (depth EQUAL), at the view's size
 * (times supersample), read back into out (may be NULL; c = 3, v->w x v->h,
 * without supersampling only).  Fills depth_ms, unlit_ms, read_ms. */
int cv_renderer_unlit(cv_renderer *r, const cv_render_view *v, cv_image *out,
                      cv_frame_timing *t, cv_err *err);

#endif
