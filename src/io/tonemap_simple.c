/* Simple Reinhard preview tone map (see tonemap_simple.h). */
#include "io/tonemap_simple.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "io/png.h"

#define CV_LOGAVG_EPS 1e-4

double cv_srgb_encode(double v) {
  return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}

/* Reads pixel i as sanitised linear RGB; flags non-finite and negative. */
static void fetch_rgb(const cv_image *img, size_t i, double rgb[3], int *nonfinite, int *negative) {
  const float *p = img->px + i * (size_t)img->c;
  float v[3];
  if (img->c == 1) {
    v[0] = v[1] = v[2] = p[0];
  } else {
    v[0] = p[0];
    v[1] = p[1];
    v[2] = p[2];
  }
  *nonfinite = *negative = 0;
  for (int k = 0; k < 3; ++k) {
    if (!isfinite(v[k])) {
      *nonfinite = 1;
      rgb[k] = 0.0;
    } else if (v[k] < 0.0f) {
      *negative = 1;
      rgb[k] = 0.0;
    } else {
      rgb[k] = v[k];
    }
  }
}

static double luminance(const double rgb[3]) {
  return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

int cv_preview_to_srgb8(const cv_image *hdr, double exposure, uint8_t *out, cv_preview_stats *stats) {
  cv_preview_stats st;
  memset(&st, 0, sizeof st);
  if (!hdr || !hdr->px || !out || hdr->w <= 0 || hdr->h <= 0) return CV_ERR_INVALID;
  if (hdr->c != 1 && hdr->c != 3 && hdr->c != 4) return CV_ERR_INVALID;
  if (isnan(exposure) || isinf(exposure)) return CV_ERR_INVALID;
  size_t n = (size_t)hdr->w * (size_t)hdr->h;
  st.pixels = n;
  double rgb[3];
  int nf, neg;
  if (exposure <= 0.0) {
    double sum = 0.0; /* log domain sum, double as required for ~1e6 pixels */
    uint64_t cnt = 0;
    for (size_t i = 0; i < n; ++i) {
      fetch_rgb(hdr, i, rgb, &nf, &neg);
      double y = luminance(rgb);
      if (nf || !(y > 0.0)) continue;
      sum += log(CV_LOGAVG_EPS + y);
      cnt++;
    }
    st.log_avg_pixels = cnt;
    if (cnt > 0) {
      st.log_avg_luminance = exp(sum / (double)cnt);
      exposure = 0.18 / st.log_avg_luminance;
    } else {
      exposure = 1.0;
    }
  }
  st.exposure = exposure;
  for (size_t i = 0; i < n; ++i) {
    fetch_rgb(hdr, i, rgb, &nf, &neg);
    st.nonfinite_pixels += (uint64_t)nf;
    st.negative_pixels += (uint64_t)neg;
    double y = luminance(rgb);
    /* Ld / Y = k / (1 + k Y); finite for any finite Y >= 0 in double */
    double s = exposure / (1.0 + exposure * y);
    for (int k = 0; k < 3; ++k) {
      double c = rgb[k] * s;
      if (c > 1.0) {
        c = 1.0;
        st.clamped_channels++;
      }
      long q = lround(255.0 * cv_srgb_encode(c));
      out[3 * i + (size_t)k] = (uint8_t)(q < 0 ? 0 : q > 255 ? 255 : q);
    }
  }
  if (stats) *stats = st;
  return CV_OK;
}

int cv_preview_write_png(const char *path, const cv_image *hdr, double exposure,
                         cv_preview_stats *stats, cv_err *err) {
  if (!hdr || hdr->w <= 0 || hdr->h <= 0)
    return cv_err_set(err, CV_ERR_INVALID, "%s: empty image", path ? path : "(null)");
  uint8_t *buf = malloc((size_t)hdr->w * (size_t)hdr->h * 3);
  if (!buf) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path ? path : "(null)");
  int rc = cv_preview_to_srgb8(hdr, exposure, buf, stats);
  if (rc != CV_OK) {
    free(buf);
    return cv_err_set(err, rc, "%s: cannot tone map (%d channels, exposure %g)", path ? path : "(null)",
                      hdr->c, exposure);
  }
  rc = cv_png_write(path, hdr->w, hdr->h, 3, buf, err);
  free(buf);
  return rc;
}
