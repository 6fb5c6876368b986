import sys

from hwsim.emulator import main

sys.exit(main())
