/* The compiled sensor kernels as one extension module. Python reaches the functions through
 * ctypes (sensors/native.py), which keeps them free of the Python C API; the module object only
 * lets setuptools build and install them like any extension (optional: without a compiler the
 * numpy and Embree paths are used).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "native.h"

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_native",
                                    "Compiled sensor kernels (called through ctypes).", -1, NULL};

PyMODINIT_FUNC PyInit__native(void) { return PyModule_Create(&module); }

#ifndef AGRINAV_SOURCE_HASH
#define AGRINAV_SOURCE_HASH "unknown"
#endif

/* the hash of the sources this build was made from (setup.py): sensors/native.py refuses a
 * build whose sources differ from those beside it */
EXPORT const char *agrinav_source_hash(void) {
    return AGRINAV_SOURCE_HASH;
}
