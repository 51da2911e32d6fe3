/* blocks.c: the element registry, from blocks/blocks.def and the
 * descriptors in blocks/. */
#include <ctype.h>
#include <string.h>

#include "lower.h"

#define BLOCK(id, kind) [id] = {kind.desc, &kind},
const BlockDesc block_desc[BK_COUNT] = {
#include "../blocks/blocks.def"
};
#undef BLOCK

int block_by_keyword(const char *s, int len) {
    for (int i = 0; i < BK_COUNT; i++) {
        const char *kw = block_desc[i].kind->keyword;
        if (kw && (int)strlen(kw) == len && !strncmp(kw, s, (size_t)len))
            return i;
    }
    return -1;
}

int block_by_letter(char c) {
    for (int i = 0; i < BK_COUNT; i++) {
        char letter = block_desc[i].kind->letter;
        if (letter && letter == toupper((unsigned char)c))
            return i;
    }
    return -1;
}

bool block_has_key(int kind, const char *key) {
    for (const KindKey *k = block_desc[kind].kind->keys; k->name; k++)
        if (!strcmp(k->name, key))
            return true;
    return false;
}
