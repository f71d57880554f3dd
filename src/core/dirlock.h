/* One writer per output folder (issue 35, defect 6): an advisory lock
 * (flock(2)) on DIR/.cave.lock, held while a run writes there.  The file
 * holds the holder's "pid P on host H since T"; a second run that finds it
 * locked refuses, naming the holder.  Released (and the file removed) by
 * cv_dirlock_release, and by the kernel when the holder dies. */
#ifndef CV_CORE_DIRLOCK_H
#define CV_CORE_DIRLOCK_H

#include "core/status.h"

/* Takes the lock of folder dir; *fd gets the lock's descriptor.  Errors:
 * CV_ERR_IO with err naming the folder and the holder
 * ("another run (pid P on host H since T) writes into DIR"), or why the
 * lock file cannot be made. */
int cv_dirlock_take(const char *dir, int *fd, cv_err *err);
/* Removes the lock file and closes fd (a no-op for fd < 0). */
void cv_dirlock_release(const char *dir, int fd);

#endif
