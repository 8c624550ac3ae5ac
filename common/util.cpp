#include "common/util.h"

#include <cctype>

namespace prt {

std::string toLower(std::string s) {
    for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

}  // namespace prt
