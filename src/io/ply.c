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

/* A PLY file being read: the stream, its name, the line number and the
 * vertex properties the header declared (3: x y z; 6: and red green blue). */
typedef struct ply_reader {
  FILE *f;
  const char *path;
  int ln;
  int nvprops;
  char line[512];
} ply_reader;

/* One 'property' or 'element face' line after the vertex element (state
 * S_PROPS or S_AFTER of read_header); *state gets the next state.  Returns
 * the status. */
enum { S_MAGIC, S_FORMAT, S_VERTEX, S_PROPS, S_FACE_PROP, S_AFTER, S_DONE };
static int header_props_line(ply_reader *r, int *state, cv_ply_points *p, cv_err *err) {
  static const char *vprops[6] = {"x", "y", "z", "red", "green", "blue"};
  const char *line = r->line, *path = r->path;
  const int ln = r->ln;
  if (*state == S_PROPS && r->nvprops < 6 && strncmp(line, "property ", 9) == 0) {
    char want[64];
    snprintf(want, sizeof want, "property float %s", vprops[r->nvprops]);
    if (strcmp(line, want) != 0)
      return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: expected '%s', got '%.60s'", path, ln, want, line);
    r->nvprops++;
    return CV_OK;
  }
  if (r->nvprops != 3 && r->nvprops != 6)
    return cv_err_set(err, CV_ERR_FORMAT,
                      "%s:%d: vertex needs x y z [red green blue] floats, has %d properties", path, ln,
                      r->nvprops);
  if (strcmp(line, "end_header") == 0) {
    *state = S_DONE;
    return CV_OK;
  }
  if (*state == S_PROPS) {
    unsigned long long nf = 0;
    char tail;
    if (sscanf(line, "element face %llu%c", &nf, &tail) == 1 && nf <= ((unsigned long long)1 << 32)) {
      p->ntris = (size_t)nf;
      *state = S_FACE_PROP;
      return CV_OK;
    }
  }
  return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: unexpected header line '%.60s'", path, ln, line);
}

/* The header, line by line (comments skipped after the magic): format,
 * vertex count and properties, the optional face element.  Returns the
 * status. */
static int read_header(ply_reader *r, cv_ply_points *p, cv_err *err) {
  const char *path = r->path, *line = r->line;
  int state = S_MAGIC;
  while (state != S_DONE) {
    if (!read_line(r->f, r->line, sizeof r->line))
      return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: header ends before 'end_header'", path, r->ln + 1);
    const int ln = ++r->ln;
    if (strncmp(line, "comment", 7) == 0 && (line[7] == ' ' || line[7] == '\0') && state != S_MAGIC)
      continue;
    switch (state) {
    case S_MAGIC:
      if (strcmp(line, "ply") != 0) return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: expected 'ply'", path, ln);
      state = S_FORMAT;
      break;
    case S_FORMAT:
      if (strcmp(line, "format ascii 1.0") == 0) {
        p->binary = 0;
      } else if (strcmp(line, "format binary_little_endian 1.0") == 0) {
        p->binary = 1;
      } else {
        return cv_err_set(err, CV_ERR_FORMAT,
                          "%s:%d: expected 'format ascii 1.0' or 'format binary_little_endian 1.0', got '%.60s'",
                          path, ln, line);
      }
      state = S_VERTEX;
      break;
    case S_VERTEX: {
      unsigned long long nv = 0;
      char tail;
      if (sscanf(line, "element vertex %llu%c", &nv, &tail) != 1 || nv > ((unsigned long long)1 << 32))
        return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: expected 'element vertex N', got '%.60s'", path, ln, line);
      p->n = (size_t)nv;
      state = S_PROPS;
      break;
    }
    case S_PROPS:
    case S_AFTER: {
      int st = header_props_line(r, &state, p, err);
      if (st) return st;
      break;
    }
    case S_FACE_PROP:
      if (strcmp(line, "property list uchar int vertex_indices") != 0)
        return cv_err_set(err, CV_ERR_FORMAT,
                          "%s:%d: expected 'property list uchar int vertex_indices', got '%.60s'", path, ln, line);
      state = S_AFTER;
      break;
    }
  }
  return CV_OK;
}

/* Vertex i's properties into v[] (binary or one text line).  Returns the status. */
static int read_vertex(ply_reader *r, const cv_ply_points *p, size_t i, float v[6], cv_err *err) {
  const int np = r->nvprops;
  if (p->binary) {
    unsigned char b[24];
    if (fread(b, 4, (size_t)np, r->f) != (size_t)np)
      return cv_err_set(err, CV_ERR_FORMAT, "%s: vertex %zu: file truncated", r->path, i);
    for (int k = 0; k < np; ++k) v[k] = get_f32le(b + 4 * k);
    return CV_OK;
  }
  r->ln++;
  if (!read_line(r->f, r->line, sizeof r->line))
    return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: vertex %zu: file truncated", r->path, r->ln, i);
  char *s = r->line, *e;
  for (int k = 0; k < np; ++k) {
    errno = 0;
    v[k] = strtof(s, &e);
    if (e == s)
      return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: vertex %zu: expected %d numbers", r->path, r->ln, i, np);
    s = e;
  }
  while (*s == ' ' || *s == '\t') s++;
  if (*s) return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: vertex %zu: extra text '%.20s'", r->path, r->ln, i, s);
  return CV_OK;
}

/* Face t's three vertex indices into idx[] (binary or one text line).
 * Returns the status. */
static int read_face(ply_reader *r, const cv_ply_points *p, size_t t, long long idx[3], cv_err *err) {
  if (p->binary) {
    unsigned char b[13];
    if (fread(b, 1, 13, r->f) != 13)
      return cv_err_set(err, CV_ERR_FORMAT, "%s: face %zu: file truncated", r->path, t);
    if (b[0] != 3)
      return cv_err_set(err, CV_ERR_FORMAT, "%s: face %zu: %u vertices; only triangles are supported", r->path,
                        t, (unsigned)b[0]);
    for (int k = 0; k < 3; ++k) idx[k] = get_i32le(b + 1 + 4 * k);
    return CV_OK;
  }
  r->ln++;
  int cnt = 0, used = 0;
  if (!read_line(r->f, r->line, sizeof r->line))
    return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: face %zu: file truncated", r->path, r->ln, t);
  if (sscanf(r->line, "%d %lld %lld %lld %n", &cnt, &idx[0], &idx[1], &idx[2], &used) != 4 || cnt != 3 ||
      r->line[used] != '\0')
    return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: face %zu: expected '3 i j k'", r->path, r->ln, t);
  return CV_OK;
}

/* The vertices, then the faces (indices checked).  Returns the status. */
static int read_elements(ply_reader *r, cv_ply_points *p, cv_err *err) {
  const int np = r->nvprops;
  p->xyz = malloc((p->n ? p->n : 1) * 3 * sizeof(float));
  if (np == 6) p->rgb = malloc((p->n ? p->n : 1) * 3 * sizeof(float));
  if (p->ntris) p->tris = malloc(p->ntris * 3 * sizeof(uint32_t));
  if (!p->xyz || (np == 6 && !p->rgb) || (p->ntris && !p->tris))
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", r->path);
  for (size_t i = 0; i < p->n; ++i) {
    float v[6];
    int st = read_vertex(r, p, i, v, err);
    if (st) return st;
    for (int k = 0; k < np; ++k)
      if (!isfinite(v[k])) return cv_err_set(err, CV_ERR_FORMAT, "%s: vertex %zu: non-finite value", r->path, i);
    memcpy(p->xyz + 3 * i, v, 3 * sizeof(float));
    if (p->rgb) memcpy(p->rgb + 3 * i, v + 3, 3 * sizeof(float));
  }
  for (size_t t = 0; t < p->ntris; ++t) {
    long long idx[3];
    int st = read_face(r, p, t, idx, err);
    if (st) return st;
    for (int k = 0; k < 3; ++k) {
      if (idx[k] < 0 || (unsigned long long)idx[k] >= p->n)
        return cv_err_set(err, CV_ERR_RANGE, "%s: face %zu: vertex index %lld outside 0..%zu", r->path, t,
                          idx[k], p->n ? p->n - 1 : 0);
      p->tris[3 * t + k] = (uint32_t)idx[k];
    }
  }
  return CV_OK;
}

/* Nothing but blank lines (text) or nothing at all (binary) after the last
 * element.  Returns the status. */
static int check_trailing(ply_reader *r, const cv_ply_points *p, cv_err *err) {
  if (p->binary)
    return fgetc(r->f) != EOF ? cv_err_set(err, CV_ERR_FORMAT, "%s: data after the last element", r->path)
                              : CV_OK;
  while (read_line(r->f, r->line, sizeof r->line)) {
    r->ln++;
    if (r->line[strspn(r->line, " \t")] != '\0')
      return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: data after the last element", r->path, r->ln);
  }
  return CV_OK;
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
  ply_reader r = {.f = f, .path = path};
  int rc = read_header(&r, p, err);
  if (!rc) rc = read_elements(&r, p, err);
  if (!rc) rc = check_trailing(&r, p, err);
  fclose(f);
  if (rc) {
    cv_ply_points_destroy(p);
    return rc;
  }
  *out = p;
  return CV_OK;
}
