/* The compiled sensor kernels as one extension module. Python reaches the functions through
 * ctypes (sensors/native.py), which keeps them free of the Python C API; the module object only
 * lets setuptools build and install them like any extension (optional: without a compiler the
 * numpy and Embree paths are used).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_native",
                                    "Compiled sensor kernels (called through ctypes).", -1, NULL};

PyMODINIT_FUNC PyInit__native(void) { return PyModule_Create(&module); }
