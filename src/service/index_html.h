/* index.html of a `cave run` output folder (docs/service.md "The output
 * folder"): the newest montage of each variant (projector / rendered /
 * viewer), lcd.png, and the plots of `cave plot` in DIR/plots, with
 * relative links and no external resources.  Written whole (a temporary
 * name, then renamed): by the master's image thread after each written
 * montage, and by `cave plot --index DIR` at the end of a run. */
#ifndef CV_SERVICE_INDEX_HTML_H
#define CV_SERVICE_INDEX_HTML_H

#include "core/status.h"

/* Scans dir and (re)writes dir/index.html.  Errors (err names the path):
 * CV_ERR_IO (the folder cannot be read, the file cannot be written),
 * CV_ERR_NOMEM. */
int cv_index_html_write(const char *dir, cv_err *err);

#endif
