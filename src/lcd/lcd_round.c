/* One progressive round of the LCD gather (gather.h, cv_lcd_render_round). */
#include "lcd/gather_internal.h"

/* --- one round, in phases -------------------------------------------------
 *
 * cv_lcd_render_round: round_setup (strategy counts, light tables), then per
 * 16 x 16 block: block_setup (texel frames and seeds, window rectangles),
 * sun_next_event (the sun's shadow ray per texel), and per chunk of
 * samples generate_rays (Sobol points -> strategy directions, rays that
 * carry no sample are added at once), order_rays (sort by direction),
 * lcdg_trace_sorted (Embree packets), shade_rays (MIS weights and radiance read
 * at the hits), then accumulate_block (texel sums into the buffer). */

/* What a round shares, read-only in the parallel part. */
typedef struct round_ctx {
  const cv_lcd_gather *g;
  const cv_lcd_light *l;
  const cv_lcd_params *p;
  uint32_t round;
  int nstr[NSTRAT], first[NSTRAT];
  float cb, cc, cw, ce, ci; /* c_s = n_s / spp */
  env_tables *et;           /* the environment strategy's tables (NULL: not used) */
  const cv_env_sampler *esr;/* et's: restricted to the panel's front */
  const cv_env_sampler *const *ereg; /* and per region (ereg[0] NULL: esr for all) */
  int_table itab;
  double clamp, inv_unit;
  int sun, sun_in_env;
  sun_disc sf;
  int chunk;
  int acc_w, acc_h; /* the buffer's tile */
} round_ctx;

static void round_free(round_ctx *R) {
  lcdg_env_tables_release(R->g, R->et);
  lcdg_int_table_free(&R->itab);
}

/* Samples per strategy and the light tables of this round (R zeroed). */
static int round_setup(const cv_lcd_gather *g, const cv_lcd_light *l, const cv_lcd_params *p,
                       uint32_t round, const cv_lcd_accum *acc, round_ctx *R) {
  const int spp = p->spp;
  R->g = g, R->l = l, R->p = p, R->round = round;
  int *nstr = R->nstr;
  /* samples per strategy and round; at least one non-window sample */
  nstr[STRAT_WIN] = g->nopen > 0 ? (int)lround(p->window_fraction * spp) : 0;
  if (nstr[STRAT_WIN] > spp - 1) nstr[STRAT_WIN] = spp - 1;
  /* environment-light tables restricted to the panel's hemisphere (the
   * light's own tables cover the whole sphere: half of their samples would
   * fall behind the panel) */
  if (p->env_fraction > 0 && l->env_smp && l->env_smp->total > 0) {
    if (!(R->et = lcdg_env_tables_get(g, l, p->eye))) return CV_ERR_NOMEM;
    R->esr = R->et->esr;
    R->ereg = (const cv_env_sampler *const *)R->et->ereg;
  }
  nstr[STRAT_ENV] = R->esr && R->esr->total > 0 ? (int)lround(p->env_fraction * spp) : 0;
  if (nstr[STRAT_ENV] > spp - 1 - nstr[STRAT_WIN]) nstr[STRAT_ENV] = spp - 1 - nstr[STRAT_WIN];
  /* interior light tables from this light's vertex radiance */
  if (p->interior_fraction > 0 && lcdg_int_table_build(g, l, &R->itab)) return CV_ERR_NOMEM;
  nstr[STRAT_INT] = R->itab.total > 0 ? (int)lround(p->interior_fraction * spp) : 0;
  if (nstr[STRAT_INT] > spp - 1 - nstr[STRAT_WIN] - nstr[STRAT_ENV])
    nstr[STRAT_INT] = spp - 1 - nstr[STRAT_WIN] - nstr[STRAT_ENV];
  const int nbc = spp - nstr[STRAT_WIN] - nstr[STRAT_ENV] - nstr[STRAT_INT];
  nstr[STRAT_BRDF] = (int)lround(p->brdf_fraction * nbc);
  nstr[STRAT_COS] = nbc - nstr[STRAT_BRDF];
  R->first[STRAT_BRDF] = 0;
  R->first[STRAT_COS] = nstr[STRAT_BRDF];
  R->first[STRAT_WIN] = R->first[STRAT_COS] + nstr[STRAT_COS];
  R->first[STRAT_ENV] = R->first[STRAT_WIN] + nstr[STRAT_WIN];
  R->first[STRAT_INT] = R->first[STRAT_ENV] + nstr[STRAT_ENV];
  R->cb = (float)nstr[STRAT_BRDF] / (float)spp, R->cc = (float)nstr[STRAT_COS] / (float)spp;
  R->cw = (float)nstr[STRAT_WIN] / (float)spp, R->ce = (float)nstr[STRAT_ENV] / (float)spp;
  R->ci = (float)nstr[STRAT_INT] / (float)spp;
  R->clamp = acc->clamp, R->inv_unit = 1 / acc->unit;
  R->sun = p->sun && l->has_sun;
  /* without next-event estimation the rays that leave find the sun's disc */
  R->sun_in_env = !p->sun && l->has_sun;
  if (l->has_sun) lcdg_sun_disc_init(l, &R->sf);
  R->chunk = spp < CHUNK_SPP ? spp : CHUNK_SPP;
  return CV_OK;
}

/* The strategy of sample j of a round. */
static inline int strategy_of(const round_ctx *R, int j) {
  return j >= R->first[STRAT_INT] ? STRAT_INT
         : j >= R->first[STRAT_ENV] ? STRAT_ENV
         : j >= R->first[STRAT_WIN] ? STRAT_WIN
         : (j >= R->first[STRAT_COS] ? STRAT_COS : STRAT_BRDF);
}

/* Sample j's ray origin on texel (x, y) from its position coordinates u[2..3]. */
static inline void sample_origin(const round_ctx *R, const texel_state *T, int x, int y,
                                 const float u[4], float o[3]) {
  const cv_lcd_panel *pn = &R->g->panel;
  const float jx = ((float)x + u[2]) / (float)R->p->w - 0.5f, jy = 0.5f - ((float)y + u[3]) / (float)R->p->h;
  for (int k = 0; k < 3; k++)
    o[k] = pn->center[k] + pn->u[k] * jx * pn->size[0] + pn->v[k] * jy * pn->size[1] + T->off[k];
}

/* The Sobol point of sample j of the round (dims 0, 1 (a (0,2)-sequence):
 * direction; 2, 3: position) and its strategy. */
static inline int sample_point(const round_ctx *R, const texel_state *T, int j, float u[4]) {
  const int st = strategy_of(R, j);
  const uint32_t idx = R->round * (uint32_t)R->nstr[st] + (uint32_t)(j - R->first[st]);
  cv_sobol_owen_tab4(&R->g->sobol, idx, T->seed[st], T->dseed[st], u);
  return st;
}

/* Per-texel state of the block (tx0, ty0, bw x bh) and its window
 * rectangles; texels whose back the eye sees are counted. */
static void block_setup(const round_ctx *R, block_buf *bb, int tx0, int ty0, int bw, int bh,
                        win_rects *wr, int64_t *cnt) {
  const cv_lcd_gather *g = R->g;
  const cv_lcd_params *p = R->p;
  const cv_lcd_panel *pn = &g->panel;
  const int w = p->w, h = p->h, aw = (int)R->acc_w, ah = (int)R->acc_h;
  wr->n = 0;
  wr->total = 0;
  if (R->nstr[STRAT_WIN] > 0) {
    const float fx = ((float)tx0 + 0.5f * (float)bw) / (float)w - 0.5f;
    const float fy = 0.5f - ((float)ty0 + 0.5f * (float)bh) / (float)h;
    const float ex = (float)bw / (float)w * pn->size[0], ey = (float)bh / (float)h * pn->size[1];
    float c[3];
    for (int k = 0; k < 3; k++)
      c[k] = pn->center[k] + pn->u[k] * fx * pn->size[0] + pn->v[k] * fy * pn->size[1];
    lcdg_block_rects(g, c, 0.5f * sqrtf(ex * ex + ey * ey), wr);
  }
  for (int i = 0; i < bw * bh; i++) {
    texel_state *T = &bb->ts[i];
    const int x = tx0 + i % bw, y = ty0 + i / bw;
    T->in_tile = x >= p->x0 && x < p->x0 + aw && y >= p->y0 && y < p->y0 + ah;
    T->aix = T->in_tile ? (size_t)(y - p->y0) * (size_t)aw + (size_t)(x - p->x0) : 0;
    memset(T->s, 0, sizeof T->s);
    memset(T->s2, 0, sizeof T->s2);
    memset(T->nee, 0, sizeof T->nee);
    float wo[3];
    const float fx = ((float)x + 0.5f) / (float)w - 0.5f, fy = 0.5f - ((float)y + 0.5f) / (float)h;
    for (int k = 0; k < 3; k++) {
      T->pc[k] = pn->center[k] + pn->u[k] * fx * pn->size[0] + pn->v[k] * fy * pn->size[1];
      wo[k] = p->eye[k] - T->pc[k];
    }
    normalize3(wo);
    const float co = dot3(wo, pn->normal);
    T->behind = !(co > 1e-6f);
    if (T->behind) {
      if (T->in_tile) cnt[CV_LCD_ACC_BEHIND] += p->spp; /* the eye sees the panel's back: black */
      continue;
    }
    for (int k = 0; k < 3; k++) T->tn[k] = wo[k] - co * pn->normal[k];
    if (!normalize3(T->tn)) memcpy(T->tn, pn->u, sizeof T->tn);
    cross3(pn->normal, T->tn, T->bn);
    /* The panel is flat: one scale-aware offset along the normal serves
     * every jittered origin of the texel. */
    cv_rt_offset_origin(T->pc, pn->normal, T->off);
    for (int k = 0; k < 3; k++) T->off[k] -= T->pc[k];
    cv_brdf_view_bins(g->smp, acosf(co > 1 ? 1 : co), &T->kb, &T->tb);
    const uint32_t tix = (uint32_t)y * (uint32_t)w + (uint32_t)x; /* panel texel: the seed */
    const uint32_t ts = cv_hash_combine(p->seed, tix);
    for (int st = 0; st < NSTRAT; st++) {
      T->seed[st] = st == STRAT_BRDF ? ts : cv_hash_combine(ts, 0x51u + (uint32_t)st);
      cv_sobol_dim_seeds(T->seed[st], 4, T->dseed[st]);
    }
  }
}

/* The sun's next-event estimate of each texel of the tile for the round,
 * from sample 0's position: one direction drawn uniformly in the solar
 * disc, one shadow ray; the term is added to every sample of the round. */
static void sun_next_event(const round_ctx *R, block_buf *bb, int tx0, int ty0, int bw, int bh,
                           int64_t *cnt) {
  if (!R->sun) return;
  const cv_lcd_panel *pn = &R->g->panel;
  for (int i = 0; i < bw * bh; i++) {
    texel_state *T = &bb->ts[i];
    if (T->behind || !T->in_tile) continue;
    float u[4], o[3], sd[3];
    sample_point(R, T, 0, u);
    sample_origin(R, T, tx0 + i % bw, ty0 + i / bw, u, o);
    const uint32_t hs = cv_hash_combine(T->seed[STRAT_BRDF] ^ 0x5017u, R->round);
    sun_disc_dir(&R->sf, hs, cv_hash_combine(hs, 0x9e3779b9u), sd);
    const float cs = dot3(sd, pn->normal);
    if (!(cs > 0)) continue;
    cnt[CV_LCD_ACC_SHADOW]++;
    if (!cv_rt_reaches_env(R->g->rt, o, sd, 0)) continue;
    cnt[CV_LCD_ACC_SUNLIT]++;
    const float th = acosf(cs > 1 ? 1 : cs);
    const float ph = fabsf(cv_fast_atan2(dot3(sd, T->bn), dot3(sd, T->tn)));
    cv_brdf_eval_bins(R->g->smp, T->kb, T->tb, th, ph, T->nee);
    for (int c = 0; c < 3; c++) T->nee[c] *= cs * R->sf.E_omega[c];
  }
}

/* Samples j0 .. j0 + nj - 1 of every texel of the block: a direction by
 * the sample's strategy and what its weight needs (f cos and the interior
 * MIS denominator, or, for window and environment samples, the local
 * direction: evaluated only if the ray leaves), appended to bb's rays with
 * their sort keys; a sample without a ray (below the horizon, a zero
 * density) is added at once as the sun term alone.  Returns the rays. */
static size_t generate_rays(const round_ctx *R, block_buf *bb, int tx0, int ty0, int bw, int bh,
                            const win_rects *wr, const cv_env_sampler *esm, int j0, int nj,
                            int64_t *cnt) {
  const cv_lcd_gather *g = R->g;
  const cv_lcd_panel *pn = &g->panel;
  const cv_brdf_sampler *smp = g->smp;
  const cv_lcd_params *p = R->p;
  const float cb = R->cb, cc = R->cc, ci = R->ci;
  size_t n = 0;
  for (int i = 0; i < bw * bh; i++) {
    texel_state *T = &bb->ts[i];
    if (T->behind) continue;
    const int x = tx0 + i % bw, y = ty0 + i / bw;
    /* the texel's points first: short independent iterations overlap */
    float uu[CHUNK_SPP][4];
    uint8_t sj[CHUNK_SPP];
    for (int j = j0; j < j0 + nj; j++) sj[j - j0] = (uint8_t)sample_point(R, T, j, uu[j - j0]);
    for (int j = j0; j < j0 + nj; j++) {
      const float *u = uu[j - j0];
      const int st = sj[j - j0];
      float o[3];
      sample_origin(R, T, x, y, u, o);
      float wl[3] = {0, 0, 0}, rd[3], th = 0, ph = 0, pb = 0, pe = 0, f[3] = {0, 0, 0};
      float pint = 0;
      uint32_t want = NO_TRI;
      int live = 0;
      if (st == STRAT_BRDF) {
        live = cv_brdf_sample(smp, T->kb, T->tb, u, wl, &th, &ph, &pb, f);
      } else if (st == STRAT_COS) {
        cv_cosine_sample(u, wl);
        live = 1;
      } else if (st == STRAT_INT) {
        /* a point on a bright interior triangle; counts only if it is the
         * ray's first hit */
        const uint32_t hh = cv_hash_combine(T->seed[STRAT_INT], R->round * (uint32_t)p->spp + (uint32_t)j);
        want = interior_sample(g, &R->itab, o, u, hh, rd, &pint);
        live = want != NO_TRI;
      } else {
        /* window, environment: f and p_b wait until the ray is known to
         * leave (only then does the sample count) */
        live = st == STRAT_ENV ? cv_env_sampler_sample(esm, u, rd, &pe) : window_sample(pn, wr, u, rd);
      }
      if (live && (st == STRAT_BRDF || st == STRAT_COS)) {
        for (int k = 0; k < 3; k++) rd[k] = T->tn[k] * wl[0] + T->bn[k] * wl[1] + pn->normal[k] * wl[2];
      } else if (live) {
        wl[0] = dot3(rd, T->tn);
        wl[1] = dot3(rd, T->bn);
        wl[2] = dot3(rd, pn->normal);
        live = st != STRAT_INT || wl[2] > 0;
      }
      if (live && (st == STRAT_COS || st == STRAT_INT)) {
        th = acosf(wl[2] > 1 ? 1 : wl[2]);
        ph = fabsf(cv_fast_atan2(wl[1], wl[0]));
        if (cb > 0) pb = cv_brdf_pdf_cs(smp, T->kb, T->tb, wl[2], wl[0] * wl[0] + wl[1] * wl[1], th, ph);
        cv_brdf_eval_bins(smp, T->kb, T->tb, th, ph, f);
      }
      const int defer = st == STRAT_WIN || st == STRAT_ENV;
      /* the interior MIS denominator; an interior-strategy ray's own
       * density is known now, the others' p_int when they hit */
      const float dint = defer ? -1.0f : cb * pb + cc * wl[2] * (float)M_1_PI + ci * pint;
      if (!(live && wl[2] > 0 && (dint > 0 || defer))) {
        /* no ray: the sample is the sun term alone */
        if (T->in_tile) add_sample((float[3]){T->nee[0], T->nee[1], T->nee[2]}, R->clamp, R->inv_unit, T->s, T->s2, cnt);
        continue;
      }
      float *ro = bb->org + 3 * n, *rdir = bb->dir + 3 * n, *rf = bb->fc + 4 * n;
      for (int k = 0; k < 3; k++) {
        ro[k] = o[k];
        rdir[k] = rd[k];
        rf[k] = defer ? wl[k] : f[k] * wl[2]; /* window, environment: the local direction */
      }
      rf[3] = dint;
      bb->tex[n] = (uint32_t)i | (defer ? TEX_WIN : 0u);
      bb->want[n] = want;
      bb->key[n] = dir_key(rd);
      if (p->ray_log && R->round == 0 && T->in_tile) {
        float *rl = p->ray_log + 6 * (T->aix * (size_t)p->spp + (size_t)j);
        memcpy(rl, ro, 3 * sizeof(float));
        memcpy(rl + 3, rd, 3 * sizeof(float));
      }
      n++;
    }
  }
  return n;
}

/* Sorts the n rays by direction and permutes them once into that order:
 * packets and shading then read consecutive memory. */
static void order_rays(block_buf *bb, size_t n) {
  lcdg_sort_by_key(bb->key, n, bb->ord, bb->tmp);
  for (size_t q = 0; q < n; q++) {
    const uint32_t r = bb->ord[q];
    memcpy(bb->sorg + 3 * q, bb->org + 3 * (size_t)r, 3 * sizeof(float));
    memcpy(bb->sdir + 3 * q, bb->dir + 3 * (size_t)r, 3 * sizeof(float));
    memcpy(bb->sfc + 4 * q, bb->fc + 4 * (size_t)r, 4 * sizeof(float));
    bb->stex[q] = bb->tex[r];
    bb->swant[q] = bb->want[r];
  }
}

/* The value of each traced sample (in direction order): MIS-weighted
 * radiance read at the interior hit or in the environment, plus the sun
 * term, added to its texel's sums. */
static void shade_rays(const round_ctx *R, block_buf *bb, size_t n, const win_rects *wr,
                       const cv_env_sampler *esm, int64_t *cnt) {
  const cv_lcd_gather *g = R->g;
  const cv_lcd_light *l = R->l;
  const cv_lcd_panel *pn = &g->panel;
  const cv_brdf_sampler *smp = g->smp;
  const cv_image *img = l->env->img;
  const float cb = R->cb, cc = R->cc, cw = R->cw, ce = R->ce, ci = R->ci;
  /* environment texels of the rays that left: computed and prefetched for
   * all of them first (they miss the cache; this overlaps the misses),
   * kept in htri / huv, which only interior hits use */
  for (size_t q = 0; q < n; q++) {
    if (bb->kind[q] != 2) continue;
    const uint32_t t = env_texel(img, bb->sdir + 3 * q, &bb->huv[2 * q], &bb->huv[2 * q + 1]);
    bb->htri[q] = t;
    const float *px = env_px(img, t);
    __builtin_prefetch(px);
    __builtin_prefetch(px + 3 * (size_t)img->w);
  }
  /* shade in direction order: consecutive rays hit nearby triangles; the
   * vertex records of a hit a few rays ahead are prefetched */
  for (size_t q = 0; q < n; q++) {
    if (q + 8 < n && bb->kind[q + 8] == 1) {
      const uint32_t *t8 = g->tri + 3 * (size_t)bb->htri[q + 8];
      __builtin_prefetch(l->vrad + 3 * (size_t)t8[0]);
      __builtin_prefetch(l->vrad + 3 * (size_t)t8[1]);
      __builtin_prefetch(l->vrad + 3 * (size_t)t8[2]);
    }
    if (q + 16 < n && bb->kind[q + 16] == 1) __builtin_prefetch(g->tri + 3 * (size_t)bb->htri[q + 16]);
    texel_state *T = &bb->ts[bb->stex[q] & ~TEX_WIN];
    if (!T->in_tile) continue;
    const int win = (bb->stex[q] & TEX_WIN) != 0;
    const float *rf = bb->sfc + 4 * q;
    float v[3] = {T->nee[0], T->nee[1], T->nee[2]};
    if (bb->kind[q] == 1) {
      cnt[CV_LCD_ACC_HITS]++;
      /* interior: MIS over BRDF, cosine and interior sampling; an
       * interior-strategy ray counts only on the triangle it aimed at */
      const uint32_t ht = bb->htri[q], aim = bb->swant[q];
      if (!win && (aim == NO_TRI || aim == ht)) {
        const uint32_t *t = g->tri + 3 * (size_t)ht;
        const float *r0 = l->vrad + 3 * (size_t)t[0], *r1 = l->vrad + 3 * (size_t)t[1],
                    *r2 = l->vrad + 3 * (size_t)t[2];
        const float hu = bb->huv[2 * q], hv = bb->huv[2 * q + 1];
        float den = rf[3];
        if (aim == NO_TRI && ci > 0) den += ci * interior_pdf(g, &R->itab, ht, bb->ht[q], bb->sdir + 3 * q);
        const float w0 = 1 - hu - hv, inv = 1 / den;
        for (int c = 0; c < 3; c++) v[c] += rf[c] * inv * (w0 * r0[c] + hu * r1[c] + hv * r2[c]);
      }
    } else if (bb->kind[q] == 2) {
      float L[3], fc[3], dint = rf[3];
      cnt[CV_LCD_ACC_ENV]++;
      if (bb->swant[q] != NO_TRI) { /* an interior-strategy ray: weight 0 outside */
        add_sample(v, R->clamp, R->inv_unit, T->s, T->s2, cnt);
        continue;
      }
      env_fetch(img, bb->htri[q], bb->huv[2 * q], bb->huv[2 * q + 1], L);
      if (R->sun_in_env && dot3(bb->sdir + 3 * q, R->sf.dir) >= R->sf.cos_a)
        for (int c = 0; c < 3; c++) L[c] += R->sf.L[c];
      if (win) {
        /* the deferred f cos and interior denominator of a window or
         * environment sample */
        const float th = acosf(rf[2] > 1 ? 1 : rf[2]), ph = fabsf(cv_fast_atan2(rf[1], rf[0]));
        const float pb = cb > 0 ? cv_brdf_pdf_cs(smp, T->kb, T->tb, rf[2], rf[0] * rf[0] + rf[1] * rf[1], th, ph) : 0.0f;
        cv_brdf_eval_bins(smp, T->kb, T->tb, th, ph, fc);
        for (int c = 0; c < 3; c++) fc[c] *= rf[2];
        dint = cb * pb + cc * rf[2] * (float)M_1_PI;
      } else {
        memcpy(fc, rf, sizeof fc);
      }
      const float den = dint + (cw > 0 ? cw * window_pdf(pn, wr, bb->sdir + 3 * q) : 0.0f) +
                        (ce > 0 ? ce * cv_env_sampler_pdf(esm, bb->sdir + 3 * q) : 0.0f);
      if (den > 0)
        for (int c = 0; c < 3; c++) v[c] += fc[c] / den * L[c];
    } else {
      cnt[CV_LCD_ACC_LOST]++;
    }
    add_sample(v, R->clamp, R->inv_unit, T->s, T->s2, cnt);
  }
}

/* The block's texel sums into the buffer (each texel belongs to one block:
 * no two threads write the same words). */
static void accumulate_block(const round_ctx *R, const block_buf *bb, int nbt, int64_t *data,
                             int aw, int ah) {
  (void)R;
  for (int i = 0; i < nbt; i++) {
    const texel_state *T = &bb->ts[i];
    if (!T->in_tile || T->behind) continue;
    int64_t *q = data + CV_LCD_ACC_HEADER + 3 * T->aix;
    for (int c = 0; c < 3; c++) q[c] += T->s[c];
    int64_t *q2 = data + CV_LCD_ACC_HEADER + 3 * (size_t)aw * (size_t)ah + 2 * T->aix;
    q2[0] += T->s2[0];
    q2[1] += T->s2[1];
  }
}

int cv_lcd_render_round(const cv_lcd_gather *g, const cv_lcd_light *l, const cv_lcd_params *p,
                        uint32_t round, cv_lcd_accum *acc) {
  if (!g || !l || !p || !acc || p->w < 1 || p->h < 1 || p->x0 < 0 || p->y0 < 0 ||
      p->x0 + acc->w > p->w || p->y0 + acc->h > p->h || p->spp < 1 ||
      l->nv != g->nv || !(p->brdf_fraction >= 0 && p->brdf_fraction <= 1) ||
      !(p->window_fraction >= 0 && p->window_fraction < 1) ||
      !(p->env_fraction >= 0 && p->env_fraction < 1) ||
      !(p->interior_fraction >= 0 && p->interior_fraction < 1) ||
      !(p->window_fraction + p->env_fraction + p->interior_fraction < 1) ||
      !isfinite(p->eye[0]) || !isfinite(p->eye[1]) || !isfinite(p->eye[2]))
    return CV_ERR_INVALID;
  if (acc->data[CV_LCD_ACC_SPP] + p->spp > CV_LCD_MAX_SPP) return CV_ERR_RANGE;
  if ((uint64_t)round * (uint64_t)p->spp + (uint64_t)p->spp > 4294967296ull) return CV_ERR_RANGE;
  round_ctx R;
  memset(&R, 0, sizeof R);
  R.acc_w = acc->w, R.acc_h = acc->h;
  if (round_setup(g, l, p, round, acc, &R)) {
    round_free(&R);
    return CV_ERR_NOMEM;
  }
  const int w = p->w, h = p->h, spp = p->spp, aw = acc->w, ah = acc->h, chunk = R.chunk;
  const int nthreads = p->threads > 0 ? p->threads : omp_get_max_threads();
  /* blocks that hold a texel of the tile */
  const int bx0 = p->x0 / BLOCK, bx1 = (p->x0 + aw - 1) / BLOCK;
  const int by0 = p->y0 / BLOCK, by1 = (p->y0 + ah - 1) / BLOCK;
  const int nbx = bx1 - bx0 + 1, nblocks = nbx * (by1 - by0 + 1);
  int64_t cnt[CV_LCD_ACC_HEADER];
  memset(cnt, 0, sizeof cnt);
  int64_t *data = acc->data;
  int status = CV_OK;

#pragma omp parallel num_threads(nthreads) reduction(+ : cnt[:CV_LCD_ACC_HEADER])
  {
    cv_rt_thread_init();
    double phase_local[CV_LCD_PHASES] = {0}, tm = 0;
    double *ph = p->phase_seconds ? phase_local : NULL;
    block_buf bb;
    int ok = lcdg_block_buf_alloc(&bb, (size_t)BLOCK * BLOCK * (size_t)chunk) == CV_OK;
    if (!ok) {
#pragma omp atomic write
      status = CV_ERR_NOMEM;
    }
#pragma omp for schedule(dynamic, 1)
    for (int bi = 0; bi < nblocks; bi++) {
      if (!ok) continue;
      const int tx0 = (bx0 + bi % nbx) * BLOCK, ty0 = (by0 + bi / nbx) * BLOCK;
      const int bw = w - tx0 < BLOCK ? w - tx0 : BLOCK, bh = h - ty0 < BLOCK ? h - ty0 : BLOCK;
      /* the environment table of the region that holds the block's centre */
      const int erx = (int)((2 * tx0 + bw) * ENV_RX / (2 * w)), ery = (int)((2 * ty0 + bh) * ENV_RY / (2 * h));
      const cv_env_sampler *esm = R.ereg && R.ereg[0] ? R.ereg[ery * ENV_RX + erx] : R.esr;
      win_rects wr;
      phase_mark(ph, CV_LCD_PHASES, &tm);
      block_setup(&R, &bb, tx0, ty0, bw, bh, &wr, cnt);
      sun_next_event(&R, &bb, tx0, ty0, bw, bh, cnt);
      phase_mark(ph, CV_LCD_PHASE_SETUP, &tm);
      for (int j0 = 0; j0 < spp; j0 += chunk) {
        const int nj = spp - j0 < chunk ? spp - j0 : chunk;
        const size_t n = generate_rays(&R, &bb, tx0, ty0, bw, bh, &wr, esm, j0, nj, cnt);
        phase_mark(ph, CV_LCD_PHASE_GENERATE, &tm);
        order_rays(&bb, n);
        phase_mark(ph, CV_LCD_PHASE_ORDER, &tm);
        lcdg_trace_sorted(g->rt, g->has_windows, &bb, n, ph, &tm);
        shade_rays(&R, &bb, n, &wr, esm, cnt);
        phase_mark(ph, CV_LCD_PHASE_SHADE, &tm);
      }
      accumulate_block(&R, &bb, bw * bh, data, aw, ah);
      phase_mark(ph, CV_LCD_PHASE_SHADE, &tm);
    }
    lcdg_block_buf_free(&bb);
    if (ph) {
#pragma omp critical(cv_lcd_phase_sum)
      for (int k = 0; k < CV_LCD_PHASES; k++) p->phase_seconds[k] += ph[k];
    }
  }
  round_free(&R);
  if (status != CV_OK) return status;
  for (int i = 0; i < CV_LCD_ACC_HEADER; i++) data[i] += cnt[i];
  data[CV_LCD_ACC_SPP] += spp;
  data[CV_LCD_ACC_ROUNDS] += 1;
  return CV_OK;
}
