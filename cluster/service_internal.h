/* Internal helpers shared by the roles of the cluster service. */
#ifndef CV_CLUSTER_SERVICE_INTERNAL_H
#define CV_CLUSTER_SERVICE_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "compensate/display.h"
#include "lcd/accum.h"
#include "prt/lightmix.h"
#include "prt/scene_light.h"
#include "render/renderer.h"
#include "service.h"

/* The compensation display (see display_gen.c); *out owned by the caller. */
int cv_service_display(const cv_service *s, cv_display **out, cv_err *err);

/* Lighting for a quantised drive state with `bands` SH bands (the full
 * path: loads the maps; used for sky drives and the LCD). */
int cv_service_build_lighting(const cv_service *s, const cv_drive_state *q, int bands,
                              cv_scene_light **out, cv_err *err);

/* The per-frame path for map drives (prt/lightmix.h); *out NULL for a sky
 * drive.  Owned by the caller. */
int cv_service_lightmix(const cv_service *s, int bands, struct cv_lightmix **out, cv_err *err);
/* Lighting and background table (width w) for a quantised drive state,
 * through mix when non-NULL, else cv_service_build_lighting.  bg may be
 * NULL (not wanted); l may be NULL (not wanted: the background alone,
 * without the SH projection). */
int cv_service_lighting(const cv_service *s, const struct cv_lightmix *mix, const cv_drive_state *q,
                        int bands, cv_lighting *l, int bg_width, cv_image **bg, cv_err *err);

/* LCD round message: this header (native byte order: the cluster is
 * homogeneous), then n int64 values of the fixed-point buffer. */
typedef struct cv_lcd_msg {
  cv_lcd_key key;   /* eye_q, light_hash = the drive's light key, setup_hash */
  uint32_t round;
  int32_t w, h;
  uint32_t contributor;
  double clamp;
  uint64_t n;
  uint32_t frame;   /* the frame whose state the round's key was taken from */
  uint32_t pad;
} cv_lcd_msg;
_Static_assert(sizeof(cv_lcd_msg) % 8 == 0, "LCD values must stay 8-byte aligned after the header");

/* The LCD image message (master -> wall-eyes): header then 3 w h floats. */
typedef struct cv_lcdimg_msg {
  uint64_t lcd_key;
  uint32_t rounds;
  int32_t w, h;
  uint32_t pad;
} cv_lcdimg_msg;

/* The master's LCD key of a frame: quantised eye and light key. */
uint64_t cv_service_lcd_key(const int32_t eye_q[3], uint64_t light_key);

/* Patch-image part of a wall-eye report: frame, then 3 n floats. */
typedef struct cv_patch_msg {
  uint32_t frame;
  uint32_t n;  /* patches of the wall */
} cv_patch_msg;

/* Desktop preview image (left-eye render rank -> master, frames marked
 * CV_FS_PREVIEW): this header, then 3 w h bytes, the uncompensated
 * tone-mapped image as 8-bit Rec.709 codes (the _uncompensated PNG's). */
typedef struct cv_preview_msg {
  uint32_t frame;
  int32_t wall;
  int32_t w, h;
} cv_preview_msg;

/* Tells the master this rank's set-up succeeded or why it failed, with the
 * content hash of the .prt it loaded (cv_prt_meta.file_hash, 0 if none):
 * the master compares every rank's with its own (issue 35, defect 5).
 * Message: 'O' or 'F', the hash (8 bytes), the text. */
void cv_service_ready(int ok, uint64_t prt_hash, const char *msg);
/* The test hook CAVE_TEST_LOAD_DELAY=MS:R1,R2,...: ranks R1, R2... wait MS
 * ms before reading the .prt (the fault test replaces the file meanwhile). */
void cv_service_test_load_delay(int rank);

/* Writes an image of display values in [0, 1] (clamped; c >= 3) as an
 * 8-bit RGB PNG. */
int cv_service_write_png01(const char *path, const cv_image *img, cv_err *err);

/* Monotonic seconds. */
double cv_service_now(void);

#endif
