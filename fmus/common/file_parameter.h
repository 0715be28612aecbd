/*
 * file_parameter.h: opening the file a String parameter names, for the FMUs
 * that read one at initialization (the replay and path controllers), so both
 * refuse an unset or unreadable file in the same words.
 */
#ifndef DSE_FILE_PARAMETER_H
#define DSE_FILE_PARAMETER_H

#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "slave.h"

/* The file at path, open for reading; NULL after logging why: the parameter
 * 'file' (`what` says what it should name) is not set, or cannot be opened. */
static inline FILE *open_file_parameter(Slave *s, const char *path, const char *what) {
    if (!path[0]) {
        slave_log(s, fmi2Error, "logStatusError", "parameter 'file' (%s) is not set", what);
        return NULL;
    }
    FILE *f = fopen(path, "r");
    if (!f) slave_log(s, fmi2Error, "logStatusError", "cannot open %s: %s", path, strerror(errno));
    return f;
}

#endif
