/* Embree's 8-ray packet queries in one loop: the caster (render/embree.py) hands over the
 * address of rtcIntersect8 or rtcOccluded8 from the Embree library it loaded, so this file needs
 * no Embree headers; one foreign call per batch instead of one per packet (384 for a 64 x 48
 * frame, each costing a Python call). */
#include "native.h"

typedef void (*packet_fn)(const void *valid, void *scene, void *packet, void *args);

EXPORT int embree_packets(const embree_packets_args_t *a) {
    if (!a) return AGN_NULL_ARRAY;
    if (a->count < 0 || a->stride < 1) return AGN_BAD_SIZE;
    if (!a->fn || (a->count > 0 && !a->first)) return AGN_NULL_ARRAY;
    packet_fn f = (packet_fn)a->fn;
    for (int64_t k = 0; k < a->count; k++) f(a->valid, a->scene, a->first + k * a->stride, NULL);
    return AGN_OK;
}
