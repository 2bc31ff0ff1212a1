/* Embree's 8-ray packet queries in one loop: the caster (sensors/embree.py) hands over the
 * address of rtcIntersect8 or rtcOccluded8 from the Embree library it loaded, so this file needs
 * no Embree headers; one foreign call per batch instead of one per packet (384 for a 64 x 48
 * frame, each costing a Python call). */
#include "native.h"

typedef void (*packet_fn)(const void *valid, void *scene, void *packet, void *args);

EXPORT void embree_packets(void *fn, const void *valid, void *scene, char *first,
                           int64_t count, int64_t stride) {
    packet_fn f = (packet_fn)fn;
    for (int64_t k = 0; k < count; k++) f(valid, scene, first + k * stride, NULL);
}
