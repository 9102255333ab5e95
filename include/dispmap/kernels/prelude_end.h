// Closes a kernel header: removes the precision-generic type spellings of prelude.h.
#undef rvec2
#undef rvec3
#undef rvec4
#undef rmat3
