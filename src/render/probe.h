/* What a host offers the renderer, asked without rendering anything: the
 * pre-flight of a multi-host CAVE (`cave cluster probe`, run on each host by
 * `cave cluster check`; docs/deploy.md "Pre-flight"). */
#ifndef CV_RENDER_PROBE_H
#define CV_RENDER_PROBE_H

#include <stddef.h>

#include "core/status.h"

/* Opens and closes the X display (a screen number past the server's screens
 * fails as in XOpenDisplay).  Errors: CV_ERR_BACKEND naming the display. */
int cv_probe_display(const char *display, cv_err *err);

/* Opens a headless GL context on the EGL device the gpu request asks for
 * (CV_GPU_AUTO, CV_GPU_SOFTWARE or a hardware index, view/cave.h), as a render
 * rank would, and writes its GL_RENDERER to renderer (cap bytes); *software
 * tells whether it is a software rasteriser.  Errors: CV_ERR_BACKEND with the
 * renderer's message ("GPU 1: no hardware EGL device 1; this machine has 1"). */
int cv_probe_gpu(int gpu, char *renderer, size_t cap, int *software, cv_err *err);

#endif
