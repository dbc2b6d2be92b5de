#pragma once

#include <charconv>
#include <string>

namespace lit::detail
{
    /** \brief The shortest text that reads back as the same number ("1000001", "1e-300", "15", "0.1"):
     *  std::to_string printed 1e-300 as 0.000000 and 15 as 15.000000, a stream 1000001 as 1e+06. */
    template <typename Number>
    std::string numberText(Number value)
    {
        char text[64];
        const std::to_chars_result end = std::to_chars(text, text + sizeof text, value);
        return std::string(text, end.ptr);
    }
}  // namespace lit::detail
