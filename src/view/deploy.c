/* Rank-to-host mapping of the render service (see deploy.h): the farm
 * hostfile parser, the plan (master, render ranks on their outputs' hosts,
 * gather ranks round-robin or from a farm, per-host slots and core lists)
 * and the rankfile / hostfile / table formatters. */
#include "view/deploy.h"

#include <ctype.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>

/* --- farm hostfile --------------------------------------------------------- */

void cv_farm_free(cv_farm *f) {
  if (!f) return;
  free(f->hosts);
  memset(f, 0, sizeof *f);
}

/* A host name as mpirun takes it: letters, digits, '.', '-', '_', ':' ('['
 * and ']' for IPv6 literals), 1..63 characters. */
static int valid_host(const char *s, size_t n) {
  if (n == 0 || n >= CV_DEPLOY_HOSTLEN) return 0;
  for (size_t i = 0; i < n; i++) {
    const unsigned char ch = (unsigned char)s[i];
    if (!isalnum(ch) && !strchr(".-_:[]", ch)) return 0;
  }
  return 1;
}

int cv_farm_parse(const char *text, const char *name, cv_farm *out, cv_err *err) {
  cv_farm f;
  memset(&f, 0, sizeof f);
  int cap = 0, line_no = 0;
  if (!name) name = "(farm)";
  const char *p = text;
  while (*p) {
    line_no++;
    const char *eol = strchr(p, '\n');
    size_t len = eol ? (size_t)(eol - p) : strlen(p);
    char line[512];
    if (len >= sizeof line) {
      cv_farm_free(&f);
      return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: line too long (expected 'host [slots=N]')", name, line_no);
    }
    memcpy(line, p, len);
    line[len] = 0;
    p = eol ? eol + 1 : p + len;
    char *hash = strchr(line, '#');
    if (hash) *hash = 0;
    /* Up to two fields, separated by blanks. */
    char *fld[3] = {NULL, NULL, NULL};
    int nf = 0;
    for (char *q = line; *q;) {
      while (*q == ' ' || *q == '\t' || *q == '\r') *q++ = 0;
      if (!*q) break;
      if (nf < 3) fld[nf] = q;
      nf++;
      while (*q && *q != ' ' && *q != '\t' && *q != '\r') q++;
    }
    if (nf == 0) continue;
    int slots = 1;
    if (nf > 2 || !valid_host(fld[0], strlen(fld[0]))) {
      cv_farm_free(&f);
      return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: expected 'host [slots=N]' (a host name without "
                        "spaces, up to %d characters), got '%s%s%s%s'", name, line_no,
                        CV_DEPLOY_HOSTLEN - 1, fld[0], nf > 1 ? " " : "", nf > 1 ? fld[1] : "",
                        nf > 2 ? " ..." : "");
    }
    if (nf == 2) {
      char *end = NULL;
      long v = 0;
      errno = 0;
      if (!strncmp(fld[1], "slots=", 6) && isdigit((unsigned char)fld[1][6])) v = strtol(fld[1] + 6, &end, 10);
      if (!end || *end || errno || v < 1 || v > CV_DEPLOY_MAX_RANKS) {
        cv_farm_free(&f);
        return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: expected 'slots=N' with N in 1..%d after the host, got '%s'",
                          name, line_no, CV_DEPLOY_MAX_RANKS, fld[1]);
      }
      slots = (int)v;
    }
    if (f.total_slots + slots > CV_DEPLOY_MAX_RANKS) {
      cv_farm_free(&f);
      return cv_err_set(err, CV_ERR_RANGE, "%s:%d: more than %d slots in all", name, line_no, CV_DEPLOY_MAX_RANKS);
    }
    if (f.n == cap) {
      int nc = cap ? 2 * cap : 16;
      cv_farm_host *h = realloc(f.hosts, (size_t)nc * sizeof *h);
      if (!h) {
        cv_farm_free(&f);
        return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", name);
      }
      f.hosts = h;
      cap = nc;
    }
    snprintf(f.hosts[f.n].name, sizeof f.hosts[f.n].name, "%s", fld[0]);
    f.hosts[f.n].slots = slots;
    f.n++;
    f.total_slots += slots;
  }
  if (f.n == 0) {
    cv_farm_free(&f);
    return cv_err_set(err, CV_ERR_EMPTY, "%s: no host (expected lines 'host [slots=N]')", name);
  }
  *out = f;
  return CV_OK;
}

int cv_farm_load(const char *path, cv_farm *out, cv_err *err) {
  FILE *fp = fopen(path, "rb");
  if (!fp) return cv_err_set(err, CV_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  size_t cap = 4096, n = 0;
  char *buf = malloc(cap);
  int st = CV_OK;
  while (buf) {
    if (n + 1 >= cap) {
      if (cap > (size_t)64 << 20) {
        st = cv_err_set(err, CV_ERR_FORMAT, "%s: larger than 64 MiB; not a hostfile", path);
        break;
      }
      char *b = realloc(buf, cap * 2);
      if (!b) {
        st = cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
        break;
      }
      buf = b;
      cap *= 2;
    }
    size_t r = fread(buf + n, 1, cap - 1 - n, fp);
    n += r;
    if (r == 0) {
      if (ferror(fp)) st = cv_err_set(err, CV_ERR_IO, "%s: cannot read: %s", path, strerror(errno));
      break;
    }
  }
  fclose(fp);
  if (!buf) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  if (st == CV_OK) {
    buf[n] = 0;
    if (memchr(buf, 0, n)) st = cv_err_set(err, CV_ERR_FORMAT, "%s: binary data; expected lines 'host [slots=N]'", path);
    else st = cv_farm_parse(buf, path, out, err);
  }
  free(buf);
  return st;
}

/* --- the plan -------------------------------------------------------------- */

void cv_deploy_free(cv_deploy *d) {
  if (!d) return;
  free(d->ranks);
  free(d->hosts);
  memset(d, 0, sizeof *d);
}

static const char *output_host(const cv_output *o) { return o->host[0] ? o->host : "localhost"; }

/* Index of host name in d->hosts, adding it when new; -1 out of memory. */
static int host_index(cv_deploy *d, int *cap, const char *name) {
  for (int i = 0; i < d->n_hosts; i++)
    if (!strcmp(d->hosts[i].name, name)) return i;
  if (d->n_hosts == *cap) {
    int nc = *cap ? 2 * *cap : 8;
    cv_deploy_host *h = realloc(d->hosts, (size_t)nc * sizeof *h);
    if (!h) return -1;
    d->hosts = h;
    *cap = nc;
  }
  snprintf(d->hosts[d->n_hosts].name, sizeof d->hosts[d->n_hosts].name, "%s", name);
  d->hosts[d->n_hosts].ranks = 0;
  return d->n_hosts++;
}

int cv_deploy_plan(const cv_cave *c, const cv_deploy_opts *o, cv_deploy *out, cv_err *err) {
  cv_deploy d;
  memset(&d, 0, sizeof d);
  if (!c || !o || !out) return cv_err_set(err, CV_ERR_INVALID, "deploy: missing argument");
  if (c->n_outputs < 1) return cv_err_set(err, CV_ERR_INVALID, "deploy: the CAVE has no outputs");
  if (!o->farm && o->n_gather < 0)
    return cv_err_set(err, CV_ERR_INVALID, "gather ranks: expected N >= 0, got %d", o->n_gather);
  if (o->cores < 0) return cv_err_set(err, CV_ERR_INVALID, "cores per host: expected N >= 0, got %d", o->cores);
  const char *master = o->master_host && o->master_host[0] ? o->master_host : output_host(&c->outputs[0]);
  if (!valid_host(master, strlen(master)))
    return cv_err_set(err, CV_ERR_INVALID, "master host: expected a host name without spaces, up to %d "
                      "characters, got '%s'", CV_DEPLOY_HOSTLEN - 1, master);
  for (int i = 0; i < c->n_outputs; i++) {
    const char *h = output_host(&c->outputs[i]);
    if (!valid_host(h, strlen(h)))
      return cv_err_set(err, CV_ERR_CONFIG, "outputs[%d].host: '%s' cannot go in a rankfile (expected "
                        "letters, digits, '.', '-', '_', ':')", i, h);
  }
  d.n_render = c->n_outputs;
  d.n_gather = o->farm ? o->farm->total_slots : o->n_gather;
  if ((long)d.n_gather + 1 + d.n_render > CV_DEPLOY_MAX_RANKS)
    return cv_err_set(err, CV_ERR_RANGE, "%d ranks: more than %d", d.n_gather + 1 + d.n_render, CV_DEPLOY_MAX_RANKS);
  d.n_ranks = 1 + d.n_render + d.n_gather;
  d.cave = c;
  d.ranks = calloc((size_t)d.n_ranks, sizeof *d.ranks);
  int hcap = 0;
  if (!d.ranks) goto nomem;

  /* The CAVE's hosts, in order of their first output (gather targets). */
  char cave_hosts[CV_CAVE_MAX_OUTPUTS][CV_DEPLOY_HOSTLEN];
  int n_cave_hosts = 0;
  for (int i = 0; i < c->n_outputs; i++) {
    const char *h = output_host(&c->outputs[i]);
    int seen = 0;
    for (int k = 0; k < n_cave_hosts && !seen; k++) seen = !strcmp(cave_hosts[k], h);
    if (!seen) snprintf(cave_hosts[n_cave_hosts++], CV_DEPLOY_HOSTLEN, "%s", h);
  }

  int farm_host = 0, farm_used = 0;
  for (int r = 0; r < d.n_ranks; r++) {
    cv_deploy_rank *k = &d.ranks[r];
    const cv_rank_role role = cv_cave_rank_role(c, r);
    k->rank = r;
    k->role = role.role;
    k->output = role.output;
    const char *h;
    if (role.role == CV_ROLE_MASTER) {
      h = master;
    } else if (role.role == CV_ROLE_RENDER) {
      h = output_host(&c->outputs[role.output]);
    } else if (o->farm) {
      while (farm_used >= o->farm->hosts[farm_host].slots) farm_host++, farm_used = 0;
      h = o->farm->hosts[farm_host].name;
      farm_used++;
    } else {
      h = cave_hosts[(r - 1 - d.n_render) % n_cave_hosts];
    }
    snprintf(k->host, sizeof k->host, "%s", h);
    const int hi = host_index(&d, &hcap, h);
    if (hi < 0) goto nomem;
    k->slot = d.hosts[hi].ranks++;
  }
  /* Core lists, now that each host's rank count is known. */
  for (int r = 0; r < d.n_ranks; r++) {
    cv_deploy_rank *k = &d.ranks[r];
    int n = 0;
    for (int i = 0; i < d.n_hosts; i++)
      if (!strcmp(d.hosts[i].name, k->host)) n = d.hosts[i].ranks;
    const int C = o->cores;
    if (C == 0) {
      snprintf(k->cores, sizeof k->cores, "%d", k->slot);
    } else if (n > C) {
      snprintf(k->cores, sizeof k->cores, "%d", k->slot % C);
    } else {
      const int a = (int)((long long)k->slot * C / n), b = (int)((long long)(k->slot + 1) * C / n - 1);
      if (a == b) snprintf(k->cores, sizeof k->cores, "%d", a);
      else snprintf(k->cores, sizeof k->cores, "%d-%d", a, b);
    }
  }
  *out = d;
  return CV_OK;
nomem:
  cv_deploy_free(&d);
  return cv_err_set(err, CV_ERR_NOMEM, "deploy: out of memory");
}

/* --- formatting ------------------------------------------------------------ */

static const char *eye_text(const cv_output *o) {
  return o->eyes == 3 ? "L+R" : (o->eyes == 1 ? "L" : "R");
}

const char *cv_deploy_role_text(const cv_deploy *d, int rank, char *buf, size_t cap) {
  const cv_deploy_rank *k = &d->ranks[rank];
  if (k->role == CV_ROLE_MASTER) {
    snprintf(buf, cap, "master");
  } else if (k->role == CV_ROLE_RENDER) {
    const cv_output *o = &d->cave->outputs[k->output];
    if (o->eyes == 3)
      snprintf(buf, cap, "render %s %s %s", d->cave->walls[o->wall].name, eye_text(o), cv_stereo_mode_name(o->stereo));
    else
      snprintf(buf, cap, "render %s %s", d->cave->walls[o->wall].name, eye_text(o));
  } else {
    snprintf(buf, cap, "gather");
  }
  return buf;
}

static void header(const cv_deploy *d, const char *what, const char *source, FILE *f) {
  fprintf(f, "# Open MPI %s written by `cave cluster`%s%s: %d ranks (1 master, %d render, %d gather) "
          "on %d host%s\n", what, source ? " from " : "", source ? source : "", d->n_ranks, d->n_render,
          d->n_gather, d->n_hosts, d->n_hosts > 1 ? "s" : "");
}

int cv_deploy_write_rankfile(const cv_deploy *d, const char *source, FILE *f) {
  header(d, "rankfile", source, f);
  fprintf(f, "# mpirun --rankfile THIS -np %d cave run ...  (slot= lists logical cores)\n", d->n_ranks);
  for (int r = 0; r < d->n_ranks; r++) {
    char role[96];
    fprintf(f, "rank %d=%s slot=%s  # %s\n", r, d->ranks[r].host, d->ranks[r].cores,
            cv_deploy_role_text(d, r, role, sizeof role));
  }
  return ferror(f) ? CV_ERR_IO : CV_OK;
}

int cv_deploy_write_hostfile(const cv_deploy *d, const char *source, FILE *f) {
  header(d, "hostfile", source, f);
  fprintf(f, "# slots: the ranks each host runs; mpirun fills hosts in order, so use the\n"
          "# rankfile to pin each rank to its output's host\n");
  for (int i = 0; i < d->n_hosts; i++) fprintf(f, "%s slots=%d\n", d->hosts[i].name, d->hosts[i].ranks);
  return ferror(f) ? CV_ERR_IO : CV_OK;
}

static void gpu_text(int g, char *buf, size_t cap) {
  if (g == CV_GPU_AUTO) snprintf(buf, cap, "auto");
  else if (g == CV_GPU_SOFTWARE) snprintf(buf, cap, "software");
  else if (g < 0) snprintf(buf, cap, "-");
  else snprintf(buf, cap, "%d", g);
}

int cv_deploy_write_table(const cv_deploy *d, FILE *f) {
  size_t hw = 4;
  for (int i = 0; i < d->n_hosts; i++) {
    size_t n = strlen(d->hosts[i].name);
    if (n > hw) hw = n;
  }
  fprintf(f, "%5s  %-26s %-*s %4s %-7s %-10s %s\n", "rank", "role", (int)hw, "host", "slot", "cores", "display", "gpu");
  for (int r = 0; r < d->n_ranks; r++) {
    const cv_deploy_rank *k = &d->ranks[r];
    char role[96], gpu[16] = "-";
    const char *disp = "-";
    if (k->role == CV_ROLE_RENDER) {
      const cv_output *o = &d->cave->outputs[k->output];
      disp = o->display[0] ? o->display : "$DISPLAY";
      gpu_text(o->gpu, gpu, sizeof gpu);
    }
    fprintf(f, "%5d  %-26s %-*s %4d %-7s %-10s %s\n", r, cv_deploy_role_text(d, r, role, sizeof role), (int)hw,
            k->host, k->slot, k->cores, disp, gpu);
  }
  fprintf(f, "hosts:");
  for (int i = 0; i < d->n_hosts; i++) fprintf(f, " %s (%d rank%s)", d->hosts[i].name, d->hosts[i].ranks,
                                              d->hosts[i].ranks > 1 ? "s" : "");
  fprintf(f, "\nranks: %d (1 master, %d render, %d gather): mpirun -np %d; cave run --check --ranks %d\n",
          d->n_ranks, d->n_render, d->n_gather, d->n_ranks, d->n_ranks);
  return ferror(f) ? CV_ERR_IO : CV_OK;
}
