// One macro that lets the same grid maths compile for the CPU and into CUDA kernels.
#pragma once

#if defined(__CUDACC__)
#define QTMV_HD __host__ __device__
#else
#define QTMV_HD
#endif
