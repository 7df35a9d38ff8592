// `hindsight config`: every field of the JSON configuration that `evaluate` and `optimize` read (and
// --set sets), with its type, default, allowed values, unit and description, from the one table of
// problems/app/config_schema.h. --markdown prints the tables of docs/reference/cli.md, which a test
// keeps equal to this output.
#include <hindsight/problems/app/config_schema.h>
#include "commands.h"

#include <iostream>
#include <memory>

namespace hindsight::cli {

void registerConfig(CLI::App& app) {
  auto markdown = std::make_shared<bool>(false);
  CLI::App* command = app.add_subcommand(
      "config", "List every configuration field (--set section.field=value) with its default and range");
  command->add_flag("--markdown", *markdown, "the Markdown tables of the CLI reference instead of text");
  commands().push_back({command, [markdown] {
                          return guarded([&] {
                            std::cout << (*markdown ? configFieldsMarkdown() : configFieldsText());
                            return 0;
                          });
                        }});
}

}  // namespace hindsight::cli
