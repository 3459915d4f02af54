/* SPDX-License-Identifier: BSD-2-Clause */
/* Messages to the host (shim.h): the host's logger with a category and a format-safe text, and
   stderr; pythonfmu's own messages relayed to the instance's current owner. */

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shim.h"

/* One message to a host's logger: its text with '%' escaped (the logger takes a printf format),
   a category always. `host` NULL or without a logger: the message goes to stderr only. */
void deliver(const fmi2CallbackFunctions *host, fmi2String instanceName, fmi2Status status,
                    const char *category, const char *message) {
    if (!category || !category[0])
        category = status == fmi2OK ? "logAll" : status == fmi2Warning ? "logStatusWarning" : "logStatusError";
    if (!host || !host->logger) {
        if (status >= fmi2Warning) fprintf(stderr, "%s: %s\n", instanceName ? instanceName : model, message);
        return;
    }
    char escaped[2 * TEXT];
    size_t j = 0;
    for (const char *p = message; *p && j + 2 < sizeof escaped; p++) {
        if (*p == '%') escaped[j++] = '%';
        escaped[j++] = *p;
    }
    escaped[j] = '\0';
    host->logger(host->componentEnvironment, instanceName ? instanceName : model, status, category, escaped);
}

/* One message to the host's logger (if any) and to stderr. */
void report(const fmi2CallbackFunctions *functions, fmi2String instanceName, fmi2Status status,
                   const char *message) {
    if (functions && functions->logger) fprintf(stderr, "%s\n", message);
    deliver(functions, instanceName, status, NULL, message);
}

/* The logger pythonfmu gets: its message (plain text: pythonfmu passes no arguments, and a '%' in
   it is not a format) to the current owner's host, with a category where pythonfmu gives none. */
void relay(fmi2ComponentEnvironment environment, fmi2String instanceName, fmi2Status status,
                  fmi2String category, fmi2String message, ...) {
    struct pooled *p = environment;
    struct instance *i = p ? p->owner : NULL;
    deliver(i ? &i->host : NULL, i ? i->name : instanceName, status, category, message ? message : "");
}

/* One message of the guard: "<function>: <reason>", to the host's logger and stderr. */
void say(struct instance *i, fmi2Status status, const char *function, const char *format, ...) {
    char text[TEXT], message[TEXT + 64];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    snprintf(message, sizeof message, "%s: %s", i->serving ? i->serving : function, text);
    report(&i->host, i->name, status, message);
}

