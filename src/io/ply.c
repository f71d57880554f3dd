/* PLY writer and reader for the point/triangle subset in ply.h. */
#include "io/ply.h"

#include "core/outfile.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static void put_f32le(unsigned char *b, float v) {
  uint32_t u;
  memcpy(&u, &v, 4);
  b[0] = (unsigned char)u;
  b[1] = (unsigned char)(u >> 8);
  b[2] = (unsigned char)(u >> 16);
  b[3] = (unsigned char)(u >> 24);
}

static float get_f32le(const unsigned char *b) {
  uint32_t u = (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) | ((uint32_t)b[3] << 24);
  float v;
  memcpy(&v, &u, 4);
  return v;
}

static int32_t get_i32le(const unsigned char *b) {
  uint32_t u = (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) | ((uint32_t)b[3] << 24);
  return (int32_t)u;
}

int cv_ply_write_points(const char *path, size_t n, const float *xyz, const float *rgb,
                        const uint32_t *tris, size_t ntris, int binary, cv_err *err) {
  if (!path || (n > 0 && !xyz) || (ntris > 0 && !tris))
    return cv_err_set(err, CV_ERR_INVALID, "cv_ply_write_points: %s: NULL data", path ? path : "(null)");
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k)
      if (!isfinite(xyz[3 * i + k]) || (rgb && !isfinite(rgb[3 * i + k])))
        return cv_err_set(err, CV_ERR_NONFINITE, "%s: vertex %zu has a non-finite %s", path, i,
                          isfinite(xyz[3 * i + k]) ? "colour" : "coordinate");
  for (size_t t = 0; t < ntris; ++t)
    for (int k = 0; k < 3; ++k)
      if (tris[3 * t + k] >= n || tris[3 * t + k] > INT32_MAX)
        return cv_err_set(err, CV_ERR_RANGE, "%s: face %zu: vertex index %u >= %zu vertices", path, t,
                          tris[3 * t + k], n);
  cv_outfile of;
  int rc = cv_outfile_open(&of, path, 1, err);
  if (rc != CV_OK) return rc;
  FILE *f = of.f;
  fprintf(f, "ply\nformat %s 1.0\ncomment written by cave (cv_ply_write_points)\n",
          binary ? "binary_little_endian" : "ascii");
  fprintf(f, "element vertex %zu\nproperty float x\nproperty float y\nproperty float z\n", n);
  if (rgb) fprintf(f, "property float red\nproperty float green\nproperty float blue\n");
  if (ntris > 0) fprintf(f, "element face %zu\nproperty list uchar int vertex_indices\n", ntris);
  fprintf(f, "end_header\n");
  for (size_t i = 0; i < n; ++i) {
    if (binary) {
      unsigned char b[24];
      for (int k = 0; k < 3; ++k) put_f32le(b + 4 * k, xyz[3 * i + k]);
      if (rgb)
        for (int k = 0; k < 3; ++k) put_f32le(b + 12 + 4 * k, rgb[3 * i + k]);
      fwrite(b, 1, rgb ? 24 : 12, f);
    } else {
      fprintf(f, "%.9g %.9g %.9g", xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
      if (rgb) fprintf(f, " %.9g %.9g %.9g", rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]);
      fputc('\n', f);
    }
  }
  for (size_t t = 0; t < ntris; ++t) {
    if (binary) {
      unsigned char b[13];
      b[0] = 3;
      for (int k = 0; k < 3; ++k) {
        uint32_t u = tris[3 * t + k];
        b[1 + 4 * k] = (unsigned char)u;
        b[2 + 4 * k] = (unsigned char)(u >> 8);
        b[3 + 4 * k] = (unsigned char)(u >> 16);
        b[4 + 4 * k] = (unsigned char)(u >> 24);
      }
      fwrite(b, 1, 13, f);
    } else {
      fprintf(f, "3 %u %u %u\n", tris[3 * t], tris[3 * t + 1], tris[3 * t + 2]);
    }
  }
  return cv_outfile_commit(&of, err);
}

void cv_ply_points_destroy(cv_ply_points *p) {
  if (!p) return;
  free(p->xyz);
  free(p->rgb);
  free(p->tris);
  free(p);
}

/* Reads one header line (without the newline) into buf; returns 0 at EOF. */
static int read_line(FILE *f, char *buf, size_t cap) {
  if (!fgets(buf, (int)cap, f)) return 0;
  size_t l = strlen(buf);
  while (l > 0 && (buf[l - 1] == '\n' || buf[l - 1] == '\r')) buf[--l] = '\0';
  return 1;
}

int cv_ply_read_points(const char *path, cv_ply_points **out, cv_err *err) {
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "cv_ply_read_points: out is NULL");
  *out = NULL;
  if (!path) return cv_err_set(err, CV_ERR_INVALID, "cv_ply_read_points: path is NULL");
  FILE *f = fopen(path, "rb");
  if (!f) return cv_err_set(err, CV_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  cv_ply_points *p = calloc(1, sizeof *p);
  if (!p) {
    fclose(f);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  }
  char line[512];
  int ln = 0, rc = CV_OK;
  /* Expected header, line by line; '*' lines are optional groups. */
  enum { S_MAGIC, S_FORMAT, S_VERTEX, S_PROPS, S_FACE_PROP, S_AFTER, S_DONE } state = S_MAGIC;
  static const char *vprops[6] = {"x", "y", "z", "red", "green", "blue"};
  int nvprops = 0, has_face = 0;
  while (state != S_DONE) {
    if (!read_line(f, line, sizeof line)) {
      rc = cv_err_set(err, CV_ERR_FORMAT, "%s:%d: header ends before 'end_header'", path, ln + 1);
      goto fail;
    }
    ln++;
    if (strncmp(line, "comment", 7) == 0 && (line[7] == ' ' || line[7] == '\0') && state != S_MAGIC)
      continue;
    switch (state) {
    case S_MAGIC:
      if (strcmp(line, "ply") != 0) {
        rc = cv_err_set(err, CV_ERR_FORMAT, "%s:%d: expected 'ply'", path, ln);
        goto fail;
      }
      state = S_FORMAT;
      break;
    case S_FORMAT:
      if (strcmp(line, "format ascii 1.0") == 0) {
        p->binary = 0;
      } else if (strcmp(line, "format binary_little_endian 1.0") == 0) {
        p->binary = 1;
      } else {
        rc = cv_err_set(err, CV_ERR_FORMAT,
                        "%s:%d: expected 'format ascii 1.0' or 'format binary_little_endian 1.0', got '%.60s'",
                        path, ln, line);
        goto fail;
      }
      state = S_VERTEX;
      break;
    case S_VERTEX: {
      unsigned long long nv = 0;
      char tail;
      if (sscanf(line, "element vertex %llu%c", &nv, &tail) != 1 || nv > ((unsigned long long)1 << 32)) {
        rc = cv_err_set(err, CV_ERR_FORMAT, "%s:%d: expected 'element vertex N', got '%.60s'", path, ln, line);
        goto fail;
      }
      p->n = (size_t)nv;
      state = S_PROPS;
      break;
    }
    case S_PROPS:
    case S_AFTER:
      if (state == S_PROPS && nvprops < 6 && strncmp(line, "property ", 9) == 0) {
        char want[64];
        snprintf(want, sizeof want, "property float %s", vprops[nvprops]);
        if (strcmp(line, want) != 0) {
          rc = cv_err_set(err, CV_ERR_FORMAT, "%s:%d: expected '%s', got '%.60s'", path, ln, want, line);
          goto fail;
        }
        nvprops++;
        break;
      }
      if (nvprops != 3 && nvprops != 6) {
        rc = cv_err_set(err, CV_ERR_FORMAT, "%s:%d: vertex needs x y z [red green blue] floats, has %d properties",
                        path, ln, nvprops);
        goto fail;
      }
      if (strcmp(line, "end_header") == 0) {
        state = S_DONE;
        break;
      }
      if (state == S_PROPS) {
        unsigned long long nf = 0;
        char tail;
        if (sscanf(line, "element face %llu%c", &nf, &tail) == 1 && nf <= ((unsigned long long)1 << 32)) {
          p->ntris = (size_t)nf;
          has_face = 1;
          state = S_FACE_PROP;
          break;
        }
      }
      rc = cv_err_set(err, CV_ERR_FORMAT, "%s:%d: unexpected header line '%.60s'", path, ln, line);
      goto fail;
    case S_FACE_PROP:
      if (strcmp(line, "property list uchar int vertex_indices") != 0) {
        rc = cv_err_set(err, CV_ERR_FORMAT,
                        "%s:%d: expected 'property list uchar int vertex_indices', got '%.60s'", path, ln, line);
        goto fail;
      }
      state = S_AFTER;
      break;
    case S_DONE:
      break;
    }
  }
  (void)has_face;
  p->xyz = malloc((p->n ? p->n : 1) * 3 * sizeof(float));
  if (nvprops == 6) p->rgb = malloc((p->n ? p->n : 1) * 3 * sizeof(float));
  if (p->ntris) p->tris = malloc(p->ntris * 3 * sizeof(uint32_t));
  if (!p->xyz || (nvprops == 6 && !p->rgb) || (p->ntris && !p->tris)) {
    rc = cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
    goto fail;
  }
  for (size_t i = 0; i < p->n; ++i) {
    float v[6];
    if (p->binary) {
      unsigned char b[24];
      if (fread(b, 4, (size_t)nvprops, f) != (size_t)nvprops) {
        rc = cv_err_set(err, CV_ERR_FORMAT, "%s: vertex %zu: file truncated", path, i);
        goto fail;
      }
      for (int k = 0; k < nvprops; ++k) v[k] = get_f32le(b + 4 * k);
    } else {
      ln++;
      if (!read_line(f, line, sizeof line)) {
        rc = cv_err_set(err, CV_ERR_FORMAT, "%s:%d: vertex %zu: file truncated", path, ln, i);
        goto fail;
      }
      char *s = line, *e;
      for (int k = 0; k < nvprops; ++k) {
        errno = 0;
        v[k] = strtof(s, &e);
        if (e == s) {
          rc = cv_err_set(err, CV_ERR_FORMAT, "%s:%d: vertex %zu: expected %d numbers", path, ln, i, nvprops);
          goto fail;
        }
        s = e;
      }
      while (*s == ' ' || *s == '\t') s++;
      if (*s) {
        rc = cv_err_set(err, CV_ERR_FORMAT, "%s:%d: vertex %zu: extra text '%.20s'", path, ln, i, s);
        goto fail;
      }
    }
    for (int k = 0; k < nvprops; ++k)
      if (!isfinite(v[k])) {
        rc = cv_err_set(err, CV_ERR_FORMAT, "%s: vertex %zu: non-finite value", path, i);
        goto fail;
      }
    memcpy(p->xyz + 3 * i, v, 3 * sizeof(float));
    if (p->rgb) memcpy(p->rgb + 3 * i, v + 3, 3 * sizeof(float));
  }
  for (size_t t = 0; t < p->ntris; ++t) {
    long long idx[3];
    if (p->binary) {
      unsigned char b[13];
      if (fread(b, 1, 13, f) != 13) {
        rc = cv_err_set(err, CV_ERR_FORMAT, "%s: face %zu: file truncated", path, t);
        goto fail;
      }
      if (b[0] != 3) {
        rc = cv_err_set(err, CV_ERR_FORMAT, "%s: face %zu: %u vertices; only triangles are supported", path, t,
                        (unsigned)b[0]);
        goto fail;
      }
      for (int k = 0; k < 3; ++k) idx[k] = get_i32le(b + 1 + 4 * k);
    } else {
      ln++;
      int cnt = 0, used = 0;
      if (!read_line(f, line, sizeof line)) {
        rc = cv_err_set(err, CV_ERR_FORMAT, "%s:%d: face %zu: file truncated", path, ln, t);
        goto fail;
      }
      if (sscanf(line, "%d %lld %lld %lld %n", &cnt, &idx[0], &idx[1], &idx[2], &used) != 4 || cnt != 3 ||
          line[used] != '\0') {
        rc = cv_err_set(err, CV_ERR_FORMAT, "%s:%d: face %zu: expected '3 i j k'", path, ln, t);
        goto fail;
      }
    }
    for (int k = 0; k < 3; ++k) {
      if (idx[k] < 0 || (unsigned long long)idx[k] >= p->n) {
        rc = cv_err_set(err, CV_ERR_RANGE, "%s: face %zu: vertex index %lld outside 0..%zu", path, t, idx[k],
                        p->n ? p->n - 1 : 0);
        goto fail;
      }
      p->tris[3 * t + k] = (uint32_t)idx[k];
    }
  }
  if (!p->binary) { /* only blank lines may follow */
    while (read_line(f, line, sizeof line)) {
      ln++;
      if (line[strspn(line, " \t")] != '\0') {
        rc = cv_err_set(err, CV_ERR_FORMAT, "%s:%d: data after the last element", path, ln);
        goto fail;
      }
    }
  } else if (fgetc(f) != EOF) {
    rc = cv_err_set(err, CV_ERR_FORMAT, "%s: data after the last element", path);
    goto fail;
  }
  fclose(f);
  *out = p;
  return CV_OK;
fail:
  fclose(f);
  cv_ply_points_destroy(p);
  return rc;
}
