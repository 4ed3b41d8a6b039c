"""``python -m akdctl`` runs the same entry point as the console script."""

from akdctl.cli.main import main

if __name__ == "__main__":
    main()
