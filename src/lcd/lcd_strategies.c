/* The LCD gather's sampling strategies and tracing (gather_internal.h):
 * block buffers, window rectangles, ray order, packet tracing, the interior
 * light table and the sun disc. */
#include "lcd/gather_internal.h"

#include <time.h>

void lcdg_block_buf_free(block_buf *b) {
  free(b->org);
  free(b->dir);
  free(b->fc);
  free(b->tex);
  free(b->key);
  free(b->ord);
  free(b->tmp);
  free(b->sorg);
  free(b->sdir);
  free(b->sfc);
  free(b->stex);
  free(b->htri);
  free(b->huv);
  free(b->ht);
  free(b->want);
  free(b->swant);
  free(b->kind);
  free(b->ts);
  memset(b, 0, sizeof *b);
}

int lcdg_block_buf_alloc(block_buf *b, size_t cap) {
  memset(b, 0, sizeof *b);
  b->cap = cap;
  b->org = malloc(3 * cap * sizeof(float));
  b->dir = malloc(3 * cap * sizeof(float));
  b->fc = malloc(4 * cap * sizeof(float));
  b->tex = malloc(cap * sizeof(uint32_t));
  b->key = malloc(cap * sizeof(uint16_t));
  b->ord = malloc(cap * sizeof(uint32_t));
  b->tmp = malloc(cap * sizeof(uint32_t));
  b->sorg = malloc(3 * cap * sizeof(float));
  b->sdir = malloc(3 * cap * sizeof(float));
  b->sfc = malloc(4 * cap * sizeof(float));
  b->stex = malloc(cap * sizeof(uint32_t));
  b->htri = malloc(cap * sizeof(uint32_t));
  b->huv = malloc(2 * cap * sizeof(float));
  b->ht = malloc(cap * sizeof(float));
  b->want = malloc(cap * sizeof(uint32_t));
  b->swant = malloc(cap * sizeof(uint32_t));
  b->kind = malloc(cap);
  b->ts = malloc(BLOCK * BLOCK * sizeof(texel_state));
  if (!b->org || !b->dir || !b->fc || !b->tex || !b->key || !b->ord || !b->tmp || !b->sorg ||
      !b->sdir || !b->sfc || !b->stex || !b->htri || !b->huv || !b->kind || !b->ts || !b->ht ||
      !b->want || !b->swant) {
    lcdg_block_buf_free(b);
    return CV_ERR_NOMEM;
  }
  return CV_OK;
}

/* The block's rectangles: each opening's vertices seen from the block's
 * centre c (behind the panel plane: pushed onto the rim), bounded, widened
 * by the angle the block's half diagonal hd subtends from the nearest
 * vertex, clipped to [-1, 1]^2.  They need not hold the openings exactly:
 * any rectangle gives an unbiased estimate (BRDF and cosine sampling cover
 * every direction); a tight one wastes fewer samples. */
void lcdg_block_rects(const cv_lcd_gather *g, const float c[3], float hd, win_rects *wr) {
  const cv_lcd_panel *pn = &g->panel;
  wr->n = 0;
  wr->total = 0;
  for (int o = 0; o < g->nopen; o++) {
    float a0 = INFINITY, a1 = -INFINITY, b0 = INFINITY, b1 = -INFINITY, dmin = INFINITY;
    int front = 0;
    for (int i = 0; i < g->open_nv[o]; i++) {
      const float *q = g->open_pos[o] + 3 * i;
      float d[3] = {q[0] - c[0], q[1] - c[1], q[2] - c[2]};
      float l = sqrtf(dot3(d, d));
      if (!(l > 0)) continue;
      dmin = fminf(dmin, l);
      float a = dot3(d, pn->u) / l, b = dot3(d, pn->v) / l, z = dot3(d, pn->normal) / l;
      if (z > 0) {
        front = 1;
      } else {
        float r = sqrtf(a * a + b * b);
        if (!(r > 0)) continue;
        a /= r, b /= r;
      }
      a0 = fminf(a0, a), a1 = fmaxf(a1, a), b0 = fminf(b0, b), b1 = fmaxf(b1, b);
    }
    if (!front) continue;
    const float m = hd / dmin;
    a0 = fmaxf(a0 - m, -1.0f), a1 = fminf(a1 + m, 1.0f);
    b0 = fmaxf(b0 - m, -1.0f), b1 = fminf(b1 + m, 1.0f);
    const float area = (a1 - a0) * (b1 - b0);
    if (!(area > 0)) continue;
    float *r = wr->r[wr->n];
    r[0] = a0, r[1] = a1, r[2] = b0, r[3] = b1;
    wr->total += area;
    wr->cum[wr->n++] = wr->total;
  }
}

/* ord = 0..n-1 stably sorted by key (LSD radix sort, two 8-bit passes). */
void lcdg_sort_by_key(const uint16_t *key, size_t n, uint32_t *ord, uint32_t *tmp) {
  size_t c0[257], c1[257];
  memset(c0, 0, sizeof c0);
  memset(c1, 0, sizeof c1);
  for (size_t i = 0; i < n; i++) {
    c0[(key[i] & 255) + 1]++;
    c1[(key[i] >> 8) + 1]++;
  }
  for (int b = 0; b < 256; b++) {
    c0[b + 1] += c0[b];
    c1[b + 1] += c1[b];
  }
  for (size_t i = 0; i < n; i++) tmp[c0[key[i] & 255]++] = (uint32_t)i;
  for (size_t i = 0; i < n; i++) {
    uint32_t j = tmp[i];
    ord[c1[key[j] >> 8]++] = j;
  }
}

/* This thread's CPU seconds (the phase_seconds hook). */
double lcdg_thread_seconds(void) {
  struct timespec t;
  if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t)) return 0;
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Window crossings of the escaped rays esc[0..ne) (indices into the
 * sorted arrays), in packets of up to CV_RT_PACKET_MAX: kind 2
 * (environment) or 3 (lost). */
static void trace_windows(const cv_rt *rt, block_buf *b, const uint32_t *esc, size_t ne) {
  float po[3 * CV_RT_PACKET_MAX] = {0}, pd[3 * CV_RT_PACKET_MAX] = {0};
  uint8_t pf[CV_RT_PACKET_MAX];
  for (size_t e0 = 0; e0 < ne; e0 += CV_RT_PACKET_MAX) {
    const int m = ne - e0 < CV_RT_PACKET_MAX ? (int)(ne - e0) : CV_RT_PACKET_MAX;
    for (int l = 0; l < m; l++) {
      memcpy(po + 3 * l, b->sorg + 3 * (size_t)esc[e0 + l], 3 * sizeof(float));
      memcpy(pd + 3 * l, b->sdir + 3 * (size_t)esc[e0 + l], 3 * sizeof(float));
    }
    cv_rt_window_any_packet(rt, m, po, pd, 0.0f, 1, pf); /* crossing or not: no hit record */
    for (int l = 0; l < m; l++) b->kind[esc[e0 + l]] = pf[l] ? 2 : 3;
  }
}

/* Traces the n sorted rays in consecutive packets: opaque closest hits,
 * then the window crossings of the rays that escaped (still in direction
 * order, in packets of their own; their indices go to b->tmp, free once
 * order_rays has permuted the rays).  kind: 1 interior, 2 environment,
 * 3 lost (escaped without crossing a window).  The two passes are marked
 * as phases of the phase_seconds hook (ph, tm: see phase_mark). */
void lcdg_trace_sorted(const cv_rt *rt, int has_windows, block_buf *b, size_t n, double *ph,
                         double *tm) {
  cv_hit hit[CV_RT_PACKET_MAX];
  uint8_t pf[CV_RT_PACKET_MAX];
  uint32_t *esc = b->tmp;
  size_t ne = 0;
  for (size_t i0 = 0; i0 < n; i0 += CV_RT_PACKET_MAX) {
    const int m = n - i0 < CV_RT_PACKET_MAX ? (int)(n - i0) : CV_RT_PACKET_MAX;
    cv_rt_intersect_packet(rt, m, b->sorg + 3 * i0, b->sdir + 3 * i0, NULL, 0.0f, INFINITY, 1, hit, pf);
    for (int l = 0; l < m; l++) {
      const size_t r = i0 + (size_t)l;
      if (pf[l]) {
        b->htri[r] = hit[l].tri;
        b->huv[2 * r] = hit[l].u;
        b->huv[2 * r + 1] = hit[l].v;
        b->ht[r] = hit[l].t;
        b->kind[r] = 1;
        continue;
      }
      b->kind[r] = 2;
      if (has_windows) esc[ne++] = (uint32_t)r;
    }
  }
  phase_mark(ph, CV_LCD_PHASE_CLOSEST, tm);
  trace_windows(rt, b, esc, ne);
  phase_mark(ph, CV_LCD_PHASE_WINDOWS, tm);
}

void lcdg_int_table_free(int_table *it) {
  free(it->prob);
  free(it->alias);
  free(it->pa);
  memset(it, 0, sizeof *it);
}

int lcdg_int_table_build(const cv_lcd_gather *g, const cv_lcd_light *l, int_table *it) {
  const size_t n = g->nt;
  memset(it, 0, sizeof *it);
  it->n = n;
  it->prob = malloc(n * sizeof(float) + 1);
  it->alias = malloc(n * sizeof(uint32_t) + 1);
  it->pa = malloc(n * sizeof(float) + 1);
  double *w = malloc(n * sizeof(double) + 1);
  uint32_t *small = malloc(n * sizeof(uint32_t) + 1), *large = malloc(n * sizeof(uint32_t) + 1);
  if (!it->prob || !it->alias || !it->pa || !w || !small || !large) {
    free(w), free(small), free(large);
    lcdg_int_table_free(it);
    return CV_ERR_NOMEM;
  }
  const cv_lcd_panel *pn = &g->panel;
  double total = 0;
  for (size_t t = 0; t < n; t++) {
    const uint32_t *v = g->tri + 3 * t;
    int front = 0;
    double y = 0;
    for (int j = 0; j < 3; j++) {
      const float *q = g->pos + 3 * (size_t)v[j], *r = l->vrad + 3 * (size_t)v[j];
      const float d[3] = {q[0] - pn->center[0], q[1] - pn->center[1], q[2] - pn->center[2]};
      front |= dot3(d, pn->normal) > 1e-4f;
      y += (0.2126 * r[0] + 0.7152 * r[1] + 0.0722 * r[2]) / 3;
    }
    /* luminance x what the panel receives of it (view factor, visibility) */
    const double e = front && y > 0 ? y * (double)g->tgeo[t] : 0.0;
    w[t] = e * g->tnA[4 * t + 3];
    it->pa[t] = (float)e;
    total += w[t];
  }
  it->total = total;
  if (!(total > 0)) {
    free(w), free(small), free(large);
    return CV_OK;
  }
  for (size_t t = 0; t < n; t++) it->pa[t] = (float)(it->pa[t] / total);
  /* Vose: scaled weights, small and large worklists */
  size_t ns = 0, nl = 0;
  for (size_t t = 0; t < n; t++) {
    w[t] = w[t] * (double)n / total;
    if (w[t] < 1) small[ns++] = (uint32_t)t;
    else large[nl++] = (uint32_t)t;
  }
  while (ns && nl) {
    const uint32_t a = small[--ns], b = large[nl - 1];
    it->prob[a] = (float)w[a];
    it->alias[a] = b;
    w[b] -= 1 - w[a];
    if (w[b] < 1) {
      nl--;
      small[ns++] = b;
    }
  }
  while (nl) it->prob[large[--nl]] = 1.0f, it->alias[large[nl]] = large[nl];
  while (ns) it->prob[small[--ns]] = 1.0f, it->alias[small[ns]] = small[ns];
  free(w), free(small), free(large);
  return CV_OK;
}

void lcdg_sun_disc_init(const cv_lcd_light *l, sun_disc *sf) {
  const double a = CV_LCD_SUN_HALF_ANGLE_DEG * M_PI / 180, s = sin(a);
  memcpy(sf->dir, l->sun_dir, sizeof sf->dir);
  sf->cos_a = (float)cos(a);
  for (int c = 0; c < 3; c++) {
    sf->L[c] = (float)(l->sun_E[c] / (M_PI * s * s));
    sf->E_omega[c] = (float)(l->sun_E[c] * 2 / (1 + cos(a)));
  }
  const float up[3] = {fabsf(sf->dir[1]) < 0.9f ? 0.0f : 1.0f, fabsf(sf->dir[1]) < 0.9f ? 1.0f : 0.0f, 0};
  cross3(up, sf->dir, sf->t);
  normalize3(sf->t);
  cross3(sf->dir, sf->t, sf->b);
}
