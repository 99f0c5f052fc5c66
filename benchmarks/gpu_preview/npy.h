// npy.h: writes a float32 array as a NumPy .npy file (format 1.0, C order).
#pragma once

#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

inline void write_npy_f32(const std::string &path, const float *data, const std::vector<size_t> &shape)
{
  std::string dims;
  size_t count = 1;
  for (size_t i = 0; i < shape.size(); ++i) {
    dims += std::to_string(shape[i]) + (shape.size() == 1 || i + 1 < shape.size() ? ", " : "");
    count *= shape[i];
  }
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" + dims + "), }";
  // Magic (6) + version (2) + length (2) + header + '\n', padded to a multiple of 64.
  size_t total = 10 + header.size() + 1;
  header.append((64 - total % 64) % 64, ' ');
  header += '\n';
  FILE *f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) throw std::runtime_error("cannot write " + path);
  const unsigned char magic[8] = {0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0};
  std::fwrite(magic, 1, 8, f);
  const unsigned short len = static_cast<unsigned short>(header.size());
  const unsigned char len_le[2] = {static_cast<unsigned char>(len & 0xff),
                                   static_cast<unsigned char>(len >> 8)};
  std::fwrite(len_le, 1, 2, f);
  std::fwrite(header.data(), 1, header.size(), f);
  std::fwrite(data, sizeof(float), count, f);
  std::fclose(f);
}
