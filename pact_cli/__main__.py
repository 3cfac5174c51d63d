from pact_cli.main import main

main()
