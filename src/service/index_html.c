/* index.html of an output folder (index_html.h). */
#include "service/index_html.h"

#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "core/outfile.h"

/* Montage variants, by the suffix after montageNNNNN_L (cluster/master_images.c). */
static const struct {
  const char *suffix, *title;
} variants[] = {
    {"", "projector image (compensated: what the projectors get)"},
    {"_uncompensated", "rendered image (the target, uncompensated)"},
    {"_viewer", "viewer (simulated: what a viewer sees with compensation)"},
    {"_viewer_uncompensated", "viewer without compensation (simulated)"},
};
#define N_VARIANTS 4

static const struct {
  const char *file, *title;
} plots[] = {
    {"frame_time.png", "Frame time"},
    {"swap_skew.png", "Swap skew"},
    {"latency.png", "Motion-to-photon latency"},
    {"readability.png", "LCD readability (contrast ratio, 3:1 line)"},
};
#define N_PLOTS 4

/* The variant of a montage file name and its frame; -1 when it is none. */
static int montage_variant(const char *name, long *frame) {
  unsigned f;
  int used = 0;
  if (sscanf(name, "montage%5u_L%n", &f, &used) != 1 || used != 14) return -1;
  const char *rest = name + used;
  const size_t n = strlen(rest);
  if (n < 4 || strcmp(rest + n - 4, ".png")) return -1;
  for (int v = 0; v < N_VARIANTS; v++)
    if (strlen(variants[v].suffix) == n - 4 && !strncmp(rest, variants[v].suffix, n - 4)) {
      *frame = (long)f;
      return v;
    }
  return -1;
}

static int exists(const char *dir, const char *name) {
  char p[4400];
  struct stat st;
  snprintf(p, sizeof p, "%s/%s", dir, name);
  return stat(p, &st) == 0 && S_ISREG(st.st_mode);
}

static void put_head(FILE *f, long n_files) {
  fprintf(f,
          "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n"
          "<title>cave run: output</title>\n<style>\n"
          "body{font-family:sans-serif;background:#111;color:#ddd;margin:1em}\n"
          "h1,h2{font-weight:normal}figure{display:inline-block;margin:0 1em 1em 0;vertical-align:top}\n"
          "img{max-width:100%%;border:1px solid #444;image-rendering:pixelated}"
          ".m,.m img{width:420px}.p,.p img{width:560px}figcaption{font-size:90%%}\n"
          "a{color:#8cf}code{color:#fc8}\n</style></head><body>\n"
          "<h1>cave run: output folder</h1>\n"
          "<p>%ld files here; the metrics are in <a href=\"metrics.jsonl\"><code>metrics.jsonl</code></a> "
          "(docs/metrics.md). The names: <code>frameNNNNN_WALL_EYE.png/.exr</code> each wall-eye, "
          "<code>montageNNNNN_L*.png</code> the left eyes unfolded.</p>\n",
          n_files);
}

static void put_body(FILE *f, const char *dir, const long *best) {
  fprintf(f, "<h2>Newest montages</h2>\n");
  int any = 0;
  for (int v = 0; v < N_VARIANTS; v++) {
    if (best[v] < 0) continue;
    any = 1;
    char name[64];
    snprintf(name, sizeof name, "montage%05ld_L%s.png", best[v], variants[v].suffix);
    fprintf(f, "<figure class=\"m\"><a href=\"%s\"><img src=\"%s\" alt=\"%s\"></a><figcaption>%s, frame %ld: <code>%s</code>"
            "</figcaption></figure>\n", name, name, variants[v].title, variants[v].title, best[v], name);
  }
  if (!any) fprintf(f, "<p>No montage yet (written with <code>--present files</code>).</p>\n");
  if (exists(dir, "lcd.png"))
    fprintf(f, "<h2>LCD panels</h2>\n<figure class=\"m\"><a href=\"lcd.png\"><img src=\"lcd.png\" alt=\"LCD panels\"></a>"
            "<figcaption>what the driver sees on each LCD panel (<code>lcd.png</code>)</figcaption></figure>\n");
  fprintf(f, "<h2>Plots of the run</h2>\n");
  any = 0;
  for (int k = 0; k < N_PLOTS; k++) {
    char rel[64];
    snprintf(rel, sizeof rel, "plots/%s", plots[k].file);
    if (!exists(dir, rel)) continue;
    any = 1;
    fprintf(f, "<figure class=\"p\"><a href=\"%s\"><img src=\"%s\" alt=\"%s\"></a><figcaption>%s</figcaption></figure>\n", rel,
            rel, plots[k].title, plots[k].title);
  }
  if (!any)
    fprintf(f, "<p>No plots yet: <code>cave plot metrics.jsonl -o plots --index .</code> in this folder "
            "draws them (cluster/main-job.sh does at the end of the job).</p>\n");
  fprintf(f, "</body></html>\n");
}

int cv_index_html_write(const char *dir, cv_err *err) {
  DIR *d = opendir(dir);
  if (!d) return cv_err_set(err, CV_ERR_IO, "%s: cannot read the folder: %s", dir, strerror(errno));
  long best[N_VARIANTS] = {-1, -1, -1, -1}, n_files = 0;
  struct dirent *e;
  while ((e = readdir(d))) {
    if (e->d_name[0] == '.') continue;
    n_files++;
    long fr;
    const int v = montage_variant(e->d_name, &fr);
    if (v >= 0 && fr > best[v]) best[v] = fr;
  }
  closedir(d);
  char path[4400];
  snprintf(path, sizeof path, "%s/index.html", dir);
  cv_outfile of;
  int st = cv_outfile_open(&of, path, 1, err);
  if (st) return st;
  put_head(of.f, n_files);
  put_body(of.f, dir, best);
  return cv_outfile_commit(&of, err);
}
